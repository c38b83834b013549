//! The predefined (OpenCV / AprilTag) dictionaries: the OpenCV-drawn markers in
//! `fixtures/markers/` (written by `cargo xtask dictionaries`) are rendered identically by
//! `fiducial` and read back with the right id and OpenCV's corner order; every family reads
//! its synthetic scenes; names resolve as documented.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::PathBuf;

use fiducial::{
    Detector, DetectorConfig, Dictionary, GrayView, RenderOptions, canonical_name,
    dictionary_by_name, render_marker, standard_dictionaries,
};
use marker_testkit::{CellPattern, SceneConfig, marker_scene};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/markers")
}

/// The ids of `dict` whose code (under some rotation) equals id `id`'s: just `id`, except in
/// `DICT_ARUCO_ORIGINAL`, whose table repeats some codes.
fn same_code(dict: &Dictionary, id: usize, other: usize) -> bool {
    let f = dict.family();
    let c = dict.codes()[id];
    (0..4).any(|q| f.rotate(dict.codes()[other], q).unwrap() == c)
}

#[test]
fn opencv_drawn_markers_render_identically_and_read_back() {
    let mut checked = 0;
    for sd in standard_dictionaries() {
        let dict = dictionary_by_name(sd.name).unwrap();
        assert_eq!(dict.len(), sd.len);
        let mut det = Detector::with_dictionary(DetectorConfig::default(), dict.clone());
        let dir = fixtures().join(sd.name);
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let id: usize = path.file_stem().unwrap().to_str().unwrap().parse().unwrap();
            let cv = image::open(&path).unwrap().to_luma8();
            let px = 10u32;
            let side = (sd.size + 2) * px;
            assert_eq!(cv.dimensions(), (side, side), "{}", path.display());
            // Same pixels as fiducial's rendering (whose quiet zone is cropped off).
            let ours = render_marker(
                dict.family(),
                dict.codes()[id],
                &RenderOptions {
                    px_per_cell: px,
                    quiet_cells: 1,
                },
            )
            .unwrap();
            for y in 0..side {
                for x in 0..side {
                    let o = ours.pixels()[((y + px) * (side + 2 * px) + x + px) as usize];
                    assert_eq!(
                        o,
                        cv.get_pixel(x, y)[0],
                        "{} id {id}: pixel ({x}, {y})",
                        sd.name
                    );
                }
            }
            // Detected on a white margin (as printed on paper), with OpenCV's corners: the
            // first is the top-left of the marker as drawn, then clockwise; pixel centres at
            // integers, so the border's outer edge is at -0.5 and side - 0.5 (+ margin).
            let margin = 2 * px as usize;
            let w = side as usize + 2 * margin;
            let mut canvas = vec![255u8; w * w];
            for y in 0..side as usize {
                for x in 0..side as usize {
                    canvas[(y + margin) * w + x + margin] = cv.get_pixel(x as u32, y as u32)[0];
                }
            }
            let mut out = Vec::new();
            det.detect(&GrayView::new(&canvas, w, w).unwrap(), &mut out);
            assert_eq!(out.len(), 1, "{} id {id}: {out:?}", sd.name);
            let d = out[0];
            assert!(
                d.index == id || same_code(dict, id, d.index),
                "{} id {id} read as {}",
                sd.name,
                d.index
            );
            assert_eq!(d.distance, 0);
            let lo = margin as f64 - 0.5;
            let hi = lo + f64::from(side);
            let expect = [[lo, lo], [hi, lo], [hi, hi], [lo, hi]];
            for (c, e) in d.corners.iter().zip(expect) {
                assert!(
                    (c.x - e[0]).abs() < 0.15 && (c.y - e[1]).abs() < 0.15,
                    "{} id {id}: corners {:?}, expected {expect:?}",
                    sd.name,
                    d.corners
                );
            }
            n += 1;
        }
        assert!(n >= 2, "{}: only {n} fixtures", sd.name);
        checked += n;
    }
    assert!(checked >= 60);
}

#[test]
fn every_family_reads_its_synthetic_scenes() {
    for sd in standard_dictionaries() {
        let dict = dictionary_by_name(sd.name).unwrap();
        let n = sd.size as usize;
        let entries = CellPattern::from_codes(n, n, dict.codes().iter().copied());
        let mut det = Detector::with_dictionary(DetectorConfig::default(), dict.clone());
        let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0013 ^ u64::from(sd.opencv_enum));
        let (mut found, mut total, mut wrong) = (0, 0, 0);
        let mut out = Vec::new();
        for _ in 0..3 {
            let cfg = SceneConfig {
                min_side: 30.0,
                ..SceneConfig::default()
            };
            let scene = marker_scene(&cfg, &entries, &mut rng).unwrap();
            det.detect(
                &GrayView::new(&scene.pixels, scene.width, scene.height).unwrap(),
                &mut out,
            );
            for m in &scene.markers {
                total += 1;
                let id = m.index.unwrap();
                let hit = out.iter().find(|d| {
                    d.corners
                        .iter()
                        .zip(&m.corners)
                        .all(|(a, b)| (a - b).norm() < 1.5)
                });
                match hit {
                    Some(d) if d.index == id || same_code(dict, id, d.index) => found += 1,
                    Some(_) => wrong += 1,
                    None => {}
                }
            }
            wrong += out.len().saturating_sub(scene.markers.len());
        }
        assert_eq!(wrong, 0, "{}: {wrong} wrong reads", sd.name);
        assert!(
            found * 10 >= total * 9,
            "{}: found {found} of {total}",
            sd.name
        );
    }
}

#[test]
fn names_resolve_case_insensitively_with_aliases() {
    assert_eq!(
        canonical_name("tag36h11").unwrap(),
        canonical_name("DICT_APRILTAG_36H11").unwrap()
    );
    assert_eq!(
        canonical_name("dict_apriltag_36h11").unwrap(),
        "DICT_APRILTAG_36h11"
    );
    assert_eq!(canonical_name("4x4_50").unwrap(), "DICT_4X4_50");
    assert_eq!(canonical_name("OWN").unwrap(), fiducial::PAPER_NAME);
    assert!(std::ptr::eq(
        dictionary_by_name("formation_4x5").unwrap(),
        Dictionary::paper()
    ));
    let err = canonical_name("tag99h1").unwrap_err().to_string();
    assert!(
        err.contains("tag99h1") && err.contains("DICT_APRILTAG_36h11"),
        "{err}"
    );
}

#[test]
fn index_distances_and_corrections_are_those_of_the_tables() {
    for sd in standard_dictionaries() {
        let dict = dictionary_by_name(sd.name).unwrap();
        let f = dict.family();
        let mut best = u32::MAX;
        let rot: Vec<[u64; 4]> = dict
            .codes()
            .iter()
            .map(|&c| core::array::from_fn(|q| f.rotate(c, q as u8).unwrap()))
            .collect();
        for (i, a) in rot.iter().enumerate() {
            for r in &a[1..] {
                best = best.min(fiducial::hamming(a[0], *r));
            }
            for b in &rot[i + 1..] {
                for r in b {
                    best = best.min(fiducial::hamming(a[0], *r));
                }
            }
        }
        assert_eq!(best, sd.min_distance, "{}", sd.name);
        assert_eq!(
            dict.max_correctable(),
            (sd.max_correction_bits * 3 / 5).min(best.saturating_sub(1) / 2)
        );
    }
    // OpenCV's defaults for the families users print most.
    assert_eq!(dictionary_by_name("tag36h11").unwrap().max_correctable(), 3);
    assert_eq!(
        dictionary_by_name("DICT_4X4_50").unwrap().max_correctable(),
        0
    );
    assert_eq!(
        dictionary_by_name("DICT_6X6_250")
            .unwrap()
            .max_correctable(),
        3
    );
}

#[test]
fn lookup_by_flips_equals_a_scan() {
    // tag36h11 with its 3-bit correction (7,807 flip sets, more than its 2,348 table
    // entries: a scan) and with 2 bits (667 sets: the flip enumeration) must agree with
    // brute force.
    let dict = dictionary_by_name("tag36h11").unwrap();
    let two = dict.clone().with_correction(2);
    let f = dict.family();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    use rand::RngExt;
    for _ in 0..300 {
        let id = rng.random_range(0..dict.len());
        let q = rng.random_range(0..4u8);
        let mut read = f.rotate(dict.codes()[id], q).unwrap();
        let flips = rng.random_range(0..5u32);
        for _ in 0..flips {
            read ^= 1 << rng.random_range(0..36);
        }
        for d in [dict, &two] {
            let fast = d.lookup(read);
            let brute = d.nearest(read);
            if brute.distance <= d.max_correctable() {
                let m = fast.unwrap();
                assert_eq!(
                    (m.index, m.rotation, m.distance),
                    (brute.index, brute.rotation, brute.distance)
                );
            } else {
                assert!(fast.is_none());
            }
        }
    }
}
