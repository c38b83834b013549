//! Real camera frames (`fixtures/realdata/duckietown/`, tag36h11, 640 x 480): every id read
//! is one AprilTag 3 reads in that frame (no wrong id), and the ids read are not fewer than
//! today's.
//!
//! Known gap (issue #13): AprilTag 3 reads 56 tags in these frames, `fiducial` 46. The
//! missed tags lie almost flat on the table, seen at a grazing angle: their thin white
//! margin blurs below the local threshold, so the black border's component merges with the
//! grey table or a neighbouring green block and no quadrilateral is traced (no quad at all,
//! not a failed decode). Recall on these frames needs quad finding that does not rely on a
//! closed dark component (AprilTag segments the black/white boundary instead).
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::PathBuf;

use fiducial::{Detector, DetectorConfig, GrayView, dictionary_by_name};

/// The ids AprilTag 3 reads per frame (fixtures/realdata/duckietown/README.md).
const APRILTAG3: &[(&str, &[usize])] = &[
    ("test_image.png", &[60, 82, 318, 328, 387]),
    ("test_image_multiple_01.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_02.png", &[22, 24, 85, 144, 198]),
    ("test_image_multiple_03.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_04.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_05.png", &[22, 24, 85, 198]),
    ("test_image_multiple_06.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_07.png", &[22, 24, 58, 85, 144, 198]),
    ("test_image_multiple_08.png", &[85, 144, 198]),
    ("test_image_multiple_09.png", &[22, 24, 58, 85, 144]),
    ("test_image_multiple_10.png", &[24, 58, 85, 198]),
];

/// Tags read today (of 56); raise it when quad finding improves.
const READ_AT_LEAST: usize = 46;

#[test]
fn duckietown_frames_read_no_wrong_id() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/realdata/duckietown");
    let dict = dictionary_by_name("tag36h11").unwrap().clone();
    let mut det = Detector::with_dictionary(DetectorConfig::default(), dict);
    let (mut read, mut expected) = (0, 0);
    let mut out = Vec::new();
    for (file, ids) in APRILTAG3 {
        let img = image::open(dir.join(file)).unwrap().to_luma8();
        let (w, h) = img.dimensions();
        det.detect(
            &GrayView::new(img.as_raw(), w as usize, h as usize).unwrap(),
            &mut out,
        );
        let mut got: Vec<usize> = out.iter().map(|d| d.index).collect();
        got.sort_unstable();
        for id in &got {
            assert!(
                ids.contains(id),
                "{file}: id {id} is not one AprilTag 3 reads ({got:?})"
            );
        }
        got.dedup();
        assert_eq!(got.len(), out.len(), "{file}: an id read twice: {out:?}");
        read += got.len();
        expected += ids.len();
    }
    assert_eq!(expected, 56);
    assert!(
        read >= READ_AT_LEAST,
        "read {read} of the {expected} tags AprilTag 3 reads (was {READ_AT_LEAST})"
    );
}
