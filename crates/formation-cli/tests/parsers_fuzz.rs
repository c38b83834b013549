//! The parser fuzz targets of `fuzz/fuzz_targets/` as stable proptests that CI runs: every
//! parser of a user file (calibration YAML, rig files, scene files, scenario files, the
//! inputs CSV, y4m streams, image files, ROS 2 bags) gets arbitrary bytes and valid files with random
//! edits, through the same bodies (`tests/fuzz_body/`) as the fuzz targets: never a panic,
//! and what a parser accepts is usable. The long campaigns (`fuzz/run-campaigns.sh`) and
//! what they found are recorded in docs/reliability.md.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod fuzz_body;

use proptest::prelude::*;

/// One edit of a byte string: replace, insert or delete one byte at a position, or splice a
/// number (with signs, exponents, infinities or NaN) over the number at a position.
#[derive(Debug, Clone)]
enum Edit {
    Replace(usize, u8),
    Insert(usize, u8),
    Delete(usize),
    Number(usize, String),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Edit::Replace(at, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Edit::Insert(at, b)),
        any::<usize>().prop_map(Edit::Delete),
        (
            any::<usize>(),
            prop_oneof![
                "-?[0-9]{1,3}(\\.[0-9]{0,4})?([eE][-+]?[0-9]{1,3})?",
                Just(".nan".to_string()),
                Just("-.inf".to_string()),
                Just("1e308".to_string()),
                Just("0".to_string()),
                Just("-0.0".to_string()),
                Just("99999999999999999999".to_string()),
            ]
        )
            .prop_map(|(at, n)| Edit::Number(at, n)),
    ]
}

/// Applies `edits` to `seed` (positions taken modulo the current length).
fn apply(seed: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut bytes = seed.to_vec();
    for e in edits {
        let len = bytes.len().max(1);
        match e {
            Edit::Replace(at, b) if !bytes.is_empty() => bytes[at % len] = *b,
            Edit::Insert(at, b) => bytes.insert(at % (bytes.len() + 1), *b),
            Edit::Delete(at) if !bytes.is_empty() => {
                bytes.remove(at % len);
            }
            Edit::Number(at, n) => {
                // The run of number characters at or after the position, if any.
                let is_num = |c: &u8| c.is_ascii_digit() || b".-+eE".contains(c);
                if let Some(start) = bytes.iter().skip(at % len).position(is_num) {
                    let start = at % len + start;
                    let end = bytes[start..]
                        .iter()
                        .position(|c| !is_num(c))
                        .map_or(bytes.len(), |e| start + e);
                    bytes.splice(start..end, n.bytes());
                }
            }
            _ => {}
        }
    }
    bytes
}

/// Text seeds: `(first byte for the YAML/JSON switch, file)`.
const CALIBRATIONS: [&str; 2] = [
    include_str!("../../../fixtures/calibration/opencv_640x480.yaml"),
    include_str!("../../../fixtures/calibration/ros_camera_info.yaml"),
];
const RIGS: [(u8, &str); 3] = [
    (0, include_str!("../../../fixtures/rigs/reference.yaml")),
    (1, include_str!("../../../fixtures/rigs/reference.json")),
    (
        0,
        include_str!("../../../fixtures/rigs/three-faces-custom-codes.yaml"),
    ),
];
const SCENES: [(u8, &str); 2] = [
    (0, include_str!("../../../fixtures/scenes/fig7.yaml")),
    (
        1,
        include_str!("../../../fixtures/scenes/three-robots-panned.json"),
    ),
];
const SCENARIOS: [(u8, &str); 3] = [
    (
        0,
        include_str!("../../../fixtures/scenarios/reference.yaml"),
    ),
    (0, include_str!("../../../fixtures/scenarios/l12-step.yaml")),
    (
        0,
        include_str!("../../../fixtures/scenarios/hard-turn.yaml"),
    ),
];
const INPUTS: &str =
    "# follower inputs\nframe,v2,w2,pan\n0,0.0,0.0,0.0\n1,0.35,0.02,0.1\n5,0.4,-0.02,0\n";
const INPUTS_T: &str = "t,w2,v2\n0.0,0.1,0.5\n0.5,0.0,0.6\n";

/// A switch byte followed by a file's text, the input format of the YAML/JSON bodies.
fn switched(json: u8, text: &str) -> Vec<u8> {
    let mut v = vec![json];
    v.extend_from_slice(text.as_bytes());
    v
}

/// A y4m stream of `frames` frames of `w x h` in the given colour space tag.
fn y4m_stream(w: usize, h: usize, colour: &str, frames: usize) -> Vec<u8> {
    let mut s = format!("YUV4MPEG2 W{w} H{h} F30:1 Ip A1:1 C{colour}\n").into_bytes();
    let c = formation_tracker_cli::y4m::Colour::parse(colour).unwrap();
    let samples = w * h + c.other_planes(w, h);
    for k in 0..frames {
        s.extend_from_slice(b"FRAME\n");
        s.extend((0..samples * c.bytes_per_sample()).map(|i| (i * 7 + k) as u8));
    }
    s
}

/// A small image encoded as `format`.
fn image_bytes(format: image::ImageFormat) -> Vec<u8> {
    let img =
        image::GrayImage::from_fn(24, 16, |x, y| image::Luma([((x * 10 + y * 3) % 256) as u8]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, format).unwrap();
    out.into_inner()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn calibration_files(seed in 0usize..2, edits in prop::collection::vec(edit(), 0..6),
                         noise in prop::collection::vec(any::<u8>(), 0..512)) {
        fuzz_body::calibration::run(&apply(CALIBRATIONS[seed].as_bytes(), &edits));
        fuzz_body::calibration::run(&noise);
    }

    #[test]
    fn rig_files(seed in 0usize..3, edits in prop::collection::vec(edit(), 0..6),
                 noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = RIGS[seed];
        fuzz_body::rig::run(&apply(&switched(json, text), &edits));
        fuzz_body::rig::run(&noise);
    }

    #[test]
    fn scene_files(seed in 0usize..2, edits in prop::collection::vec(edit(), 0..6),
                   noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = SCENES[seed];
        fuzz_body::scene::run(&apply(&switched(json, text), &edits));
        fuzz_body::scene::run(&noise);
    }

    #[test]
    fn scenario_files(seed in 0usize..3, edits in prop::collection::vec(edit(), 0..6),
                      noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = SCENARIOS[seed];
        fuzz_body::scenario::run(&apply(&switched(json, text), &edits));
        fuzz_body::scenario::run(&noise);
    }

    #[test]
    fn inputs_csv(seed in 0usize..2, edits in prop::collection::vec(edit(), 0..6),
                  noise in prop::collection::vec(any::<u8>(), 0..512)) {
        fuzz_body::inputs::run(&apply([INPUTS, INPUTS_T][seed].as_bytes(), &edits));
        fuzz_body::inputs::run(&noise);
    }

    #[test]
    fn y4m_streams(colour in prop::sample::select(vec!["mono", "420jpeg", "444", "mono16"]),
                   w in 1usize..40, h in 1usize..40, frames in 0usize..3,
                   edits in prop::collection::vec(edit(), 0..6),
                   noise in prop::collection::vec(any::<u8>(), 0..512)) {
        fuzz_body::y4m::run(&apply(&y4m_stream(w, h, colour, frames), &edits));
        fuzz_body::y4m::run(&noise);
    }

    #[test]
    fn image_files(png in any::<bool>(), edits in prop::collection::vec(edit(), 0..6),
                   noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let format = if png { image::ImageFormat::Png } else { image::ImageFormat::Jpeg };
        fuzz_body::image::run(&apply(&image_bytes(format), &edits));
        fuzz_body::image::run(&noise);
    }
}

/// The smaller fixture bag (lz4 chunks, the demo's frames): edits of its bytes reach the
/// MCAP records, the chunk decompression, the CDR messages and the images.
const BAG: &[u8] = include_bytes!("../../../fixtures/bags/demo_lz4.mcap");

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn bags(edits in prop::collection::vec(edit(), 0..6),
            cut in any::<usize>(),
            noise in prop::collection::vec(any::<u8>(), 0..512)) {
        // Edits anywhere, and the same edits on a file cut short (a recording that stopped).
        let edited = apply(BAG, &edits);
        let _ = fuzz_body::bag::run(&edited);
        let _ = fuzz_body::bag::run(&edited[..cut % (edited.len() + 1)]);
        let mut magic = b"\x89MCAP0\r\n".to_vec();
        magic.extend_from_slice(&noise);
        let _ = fuzz_body::bag::run(&magic);
    }
}

#[test]
fn the_seeds_are_accepted() {
    // The edits start from inputs the parsers accept, so the proptests explore near them.
    for text in CALIBRATIONS {
        assert!(pose::calib::Calibration::from_yaml_str(text).is_ok());
    }
    let dict = fiducial::Dictionary::paper();
    for (json, text) in RIGS {
        formation_tracker::rig::RigModel::from_text(text, json == 1, "seed", dict).unwrap();
    }
    for (json, text) in SCENES {
        formation_sim::scene::SceneSpec::from_text(text, json == 1, "seed").unwrap();
    }
    for (json, text) in SCENARIOS {
        formation_sim::scenario_file::ScenarioSpec::parse(
            text,
            json == 1,
            std::path::Path::new("seed"),
        )
        .unwrap();
    }
    for text in [INPUTS, INPUTS_T] {
        formation_tracker_cli::inputs::FollowerInputs::parse(text).unwrap();
    }
    for colour in ["mono", "420jpeg", "444", "mono16"] {
        let s = y4m_stream(5, 3, colour, 1);
        let header = formation_tracker_cli::y4m::parse_header(
            &s[..s.iter().position(|&b| b == b'\n').unwrap()],
        );
        assert!(header.is_ok(), "{colour}: {header:?}");
    }
    assert_eq!(
        fuzz_body::bag::run(BAG),
        2,
        "both frames of the seed bag are read"
    );
    for format in [image::ImageFormat::Png, image::ImageFormat::Jpeg] {
        let img = formation_tracker_cli::frames::decode_grey(&image_bytes(format), 64).unwrap();
        assert_eq!((img.width, img.height, img.data.len()), (24, 16, 24 * 16));
    }
}

/// Runs on several threads at once each get their own scratch file: they used to share four
/// (the run number modulo 4), so a seed run could read a file another thread was rewriting or
/// had just removed, and `the_seeds_are_accepted` failed on a clean-clone CI run (0 frames read).
#[test]
fn concurrent_runs_do_not_share_a_file() {
    std::thread::scope(|s| {
        for _ in 0..8 {
            s.spawn(|| {
                for _ in 0..6 {
                    assert_eq!(fuzz_body::bag::run(BAG), 2, "both frames of the seed bag");
                }
            });
        }
    });
}
