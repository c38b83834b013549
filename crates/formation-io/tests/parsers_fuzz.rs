//! The parser fuzz targets of `fuzz/fuzz_targets/` for this crate's readers as stable
//! proptests that CI runs: rig files, controller files, the inputs CSV, y4m streams, image files and ROS 2 bags
//! get arbitrary bytes and valid files with random edits, through the same bodies
//! (`tests/fuzz_body/`) as the fuzz targets: never a panic, and what a parser accepts is
//! usable. The long campaigns (`fuzz/run-campaigns.sh`) and what they found are recorded in
//! docs/reliability.md.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

mod fuzz_body;

use marker_testkit::edits::{apply, edit, switched};
use proptest::prelude::*;

/// Text seeds: `(first byte for the YAML/JSON switch, file)`.
const RIGS: [(u8, &str); 3] = [
    (0, include_str!("../../../fixtures/rigs/reference.yaml")),
    (1, include_str!("../../../fixtures/rigs/reference.json")),
    (
        0,
        include_str!("../../../fixtures/rigs/three-faces-custom-codes.yaml"),
    ),
];
/// Controller file seeds `(first byte for the YAML/JSON switch, file)`.
const CONTROLLERS: [(u8, &str); 2] = [
    (
        0,
        "leader: 1\nl12_desired: 1.03\nalpha12_desired: 0.245\nk_l: 1.0\nk_alpha: 1.0\nmax_v: 1.5\n",
    ),
    (
        1,
        r#"{"leader": 2, "l12_desired": 1.5, "alpha12_desired": -0.1, "k_l": 0.8, "k_alpha": 1.2}"#,
    ),
];
const INPUTS: &str =
    "# follower inputs\nframe,v2,w2,pan\n0,0.0,0.0,0.0\n1,0.35,0.02,0.1\n5,0.4,-0.02,0\n";
const INPUTS_T: &str = "t,w2,v2\n0.0,0.1,0.5\n0.5,0.0,0.6\n";

/// A y4m stream of `frames` frames of `w x h` in the given colour space tag.
fn y4m_stream(w: usize, h: usize, colour: &str, frames: usize) -> Vec<u8> {
    let mut s = format!("YUV4MPEG2 W{w} H{h} F30:1 Ip A1:1 C{colour}\n").into_bytes();
    let c = formation_io::y4m::Colour::parse(colour).unwrap();
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
    fn rig_files(seed in 0usize..3, edits in prop::collection::vec(edit(), 0..6),
                 noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = RIGS[seed];
        fuzz_body::rig::run(&apply(&switched(json, text), &edits));
        fuzz_body::rig::run(&noise);
    }

    #[test]
    fn controller_files(seed in 0usize..2, edits in prop::collection::vec(edit(), 0..6),
                        noise in prop::collection::vec(any::<u8>(), 0..512)) {
        let (json, text) = CONTROLLERS[seed];
        fuzz_body::controller::run(&apply(&switched(json, text), &edits));
        fuzz_body::controller::run(&noise);
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
    let dict = fiducial::Dictionary::paper();
    for (json, text) in RIGS {
        formation_io::rigfile::from_text(text, json == 1, "seed", dict).unwrap();
    }
    for (json, text) in CONTROLLERS {
        formation_io::controller::from_text(text, json == 1, "seed").unwrap();
    }
    for text in [INPUTS, INPUTS_T] {
        formation_io::inputs::FollowerInputs::parse(text).unwrap();
    }
    for colour in ["mono", "420jpeg", "444", "mono16"] {
        let s = y4m_stream(5, 3, colour, 1);
        let header =
            formation_io::y4m::parse_header(&s[..s.iter().position(|&b| b == b'\n').unwrap()]);
        assert!(header.is_ok(), "{colour}: {header:?}");
    }
    assert_eq!(
        fuzz_body::bag::run(BAG),
        2,
        "both frames of the seed bag are read"
    );
    for format in [image::ImageFormat::Png, image::ImageFormat::Jpeg] {
        let img = formation_io::frames::decode_grey(&image_bytes(format), 64).unwrap();
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
