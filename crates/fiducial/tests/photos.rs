//! OpenCV's sample photographs (`fixtures/realdata/photos/`, see its README): ordinary
//! photos with no marker, and the photo of OpenCV's ArUco tutorial, read with every
//! dictionary name `--dictionary` accepts, boundary clustering off and on.
//!
//! History (issue #31): with boundary clustering on, every `DICT_4X4_*` dictionary read id
//! 17 on `board.jpg`, a chessboard calibration photo: the cluster quad around a dark blob
//! 13 px across with a highlight inside it, on grey. Its light cells were the highlight and
//! it read exactly, and the side check had no evidence against it (cells of 2.2 px, and no
//! side's outside lighter than its border by 0.4 of the contrast). The side check now asks
//! some side of a marker to show a light outside.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::{Path, PathBuf};

use fiducial::{Decoded, Detector, GrayView};

mod common;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/realdata/photos")
}

/// The photos (JPEG and PNG) of `sub`, sorted.
fn photos(sub: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir().join(sub))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("jpg" | "png")))
        .collect();
    v.sort();
    v
}

/// Every reading of `photo` by each of `detectors`: (dictionary name, marker).
fn reads(photo: &Path, detectors: &mut [(&'static str, Detector)]) -> Vec<(&'static str, Decoded)> {
    let img = image::open(photo).unwrap().to_luma8();
    let (w, h) = img.dimensions();
    let view = GrayView::new(img.as_raw(), w as usize, h as usize).unwrap();
    let mut all = Vec::new();
    let mut out = Vec::new();
    for (name, det) in detectors.iter_mut() {
        det.detect(&view, &mut out);
        all.extend(out.iter().map(|d| (*name, *d)));
    }
    all
}

fn centre(d: &Decoded) -> [f64; 2] {
    d.corners
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p.x / 4.0, s[1] + p.y / 4.0])
}

/// No dictionary reads anything on a photo without markers, boundary clustering off or on.
#[test]
fn no_dictionary_reads_anything_on_photos_without_markers() {
    let notags = photos("notags");
    assert!(notags.len() >= 13, "{} photos", notags.len());
    let mut false_reads = Vec::new();
    for clusters in [false, true] {
        let mut dets = common::dictionary_detectors(clusters, None);
        assert!(dets.len() >= 20, "{} dictionaries", dets.len());
        for photo in &notags {
            for (name, d) in reads(photo, &mut dets) {
                false_reads.push(format!(
                    "{} clusters {clusters}: {name} id {} ({} bits corrected) at {:?}",
                    photo.file_name().unwrap().to_string_lossy(),
                    d.index,
                    d.distance,
                    centre(&d)
                ));
            }
        }
    }
    assert!(
        false_reads.is_empty(),
        "false reads:\n{}",
        false_reads.join("\n")
    );
}

/// The six `DICT_6X6_250` markers of OpenCV's ArUco photo are read, boundary clustering off
/// or on, and no dictionary reads anything anywhere else on it.
#[test]
fn aruco_photo_reads_its_six_markers_and_nothing_else() {
    let photo = dir().join("aruco/singlemarkersoriginal.jpg");
    for clusters in [false, true] {
        let all = reads(&photo, &mut common::dictionary_detectors(clusters, None));
        let mut ids: Vec<usize> = all
            .iter()
            .filter(|(name, _)| *name == "DICT_6X6_250")
            .map(|(_, d)| d.index)
            .collect();
        ids.sort_unstable();
        assert_eq!(ids, [23, 40, 62, 98, 124, 203], "clusters {clusters}");
        let markers: Vec<[f64; 2]> = all
            .iter()
            .filter(|(name, _)| *name == "DICT_6X6_250")
            .map(|(_, d)| centre(d))
            .collect();
        for (name, d) in &all {
            let c = centre(d);
            assert!(
                markers
                    .iter()
                    .any(|m| (m[0] - c[0]).hypot(m[1] - c[1]) < 3.0),
                "clusters {clusters}: {name} id {} at {c:?}, where no marker is",
                d.index
            );
        }
    }
}
