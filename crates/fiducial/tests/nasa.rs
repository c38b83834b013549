//! A real photograph of robots carrying tag36h11 tags at many angles
//! (`fixtures/realdata/nasa/`, CC BY-SA 2.0, see its README), with AprilTag 3's reading of
//! ten tags as the reference.
//!
//! History (issue #31): 6 of the 10 before the side check also tried the corners fitted to
//! the decoded pattern. Two tags seen obliquely (cells of 2-3 px across their narrow sides)
//! were dropped as "a side along an occluder": with the plain corners the grid put their
//! inner border edges 0.56 and 0.71 px off, against tolerances of 0.52 and 0.47 px. One of
//! them is read now, and so is a tag the reference does not list (on the left face of a
//! cube, almost edge-on). 8 of the 10 since the side check measures the border's cells
//! across the side rather than along the grid's slanted lines: the reference's eighth, a tag
//! lying almost flat (a parallelogram with 33 degree corners), was dropped because the
//! slant made its 1.2 px border cells read as 2.1 px ones, held to a check they cannot pass.
//! Two tags gave no quad with the default settings: the third's border touches the dark
//! floor through a light rim of 1-2 px, and the ninth, lying flat, has corners of 21
//! degrees, under the quad fit's 30 of then; the fit takes 15 since 2026-12-07, and the
//! ninth is read by default too, with two tags the reference lacks (the edge-on one and one
//! lying flat right of the ninth). Boundary clustering (`formation-tracker detect`'s
//! search) finds the third's quad, which the side check dropped until it took the corner
//! cell's level above the border's black near that corner: glare lights the border
//! unevenly there (cells 7 to 68 grey levels, contrast 80; its NW corner cell read 0.456 of
//! the contrast against 0.432 allowed, with the reference corners 0.420 against 0.422). Its
//! edges are sharp (25-75 % rise 0.62-0.77 px, under the 1.5 px the corner allowance
//! assumes), so no allowance derived from the blur would have let it pass. Clustering also
//! finds the ninth (its quads may have corners of 15 degrees), 2.3 px off at one 21 degree
//! tip: a side's offset moves a tip 1 / sin 21 deg = 2.8 times as far, and the two sides
//! there lie 0.29 and up to 0.57 px from AprilTag 3's (on a tag 6 px high, border cells of
//! 1.2 px), with the pattern step (2.30 px) or without it (2.32 px). On tags of its shape
//! drawn with an exact truth, AprilTag 3's own corners lie 1.0-3.1 px from it and ours
//! 0.1-0.7 px (`docs/grazing-angles.md`, `cargo xtask grazing`): at such tips the reference
//! is as far from the truth as our reading is from the reference.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::PathBuf;

use fiducial::{Decoded, Detector, DetectorConfig, GrayView, dictionary_by_name};
use marker_testkit::reference::{RefTag, corner_error};

mod common;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/realdata/nasa")
}

/// The reference tags (AprilTag 3's corners, in our pixel convention).
fn reference() -> Vec<RefTag> {
    let text = std::fs::read_to_string(dir().join("34139872896_defdb2f8d9_c.txt")).unwrap();
    marker_testkit::reference::parse(&text).unwrap()
}

/// The photo, as grey.
fn photo() -> image::GrayImage {
    image::open(dir().join("34139872896_defdb2f8d9_c.jpg"))
        .unwrap()
        .to_luma8()
}

/// The tag on the cube's left face, almost edge-on, which the reference does not list
/// (rounded corners).
const EDGE_ON: [[f64; 2]; 4] = [
    [393.0, 247.0],
    [399.0, 283.0],
    [385.0, 308.0],
    [380.0, 272.0],
];

/// The tag lying flat to the right of the reference's ninth, which the reference does not
/// list either (rounded corners).
const FLAT_RIGHT: [[f64; 2]; 4] = [
    [747.4, 361.1],
    [783.8, 365.4],
    [756.8, 372.1],
    [720.7, 367.7],
];

/// Whether `d` is a tag of the photo: a reference tag within a pixel, the ninth at its 21
/// degree tips (2.3 px), or one of the two tags the reference does not list.
fn known(d: &Decoded, refs: &[RefTag]) -> bool {
    refs.iter().any(|r| corner_error(&d.corners, &r.1) <= 1.0)
        || corner_error(&d.corners, &refs[8].1) <= 2.5
        || [EDGE_ON, FLAT_RIGHT]
            .iter()
            .any(|e| corner_error(&d.corners, e) <= 2.0)
}

/// The markers read on the photo by a tag36h11 detector with `config`.
fn detect_photo(config: DetectorConfig) -> Vec<Decoded> {
    let img = photo();
    let (w, h) = img.dimensions();
    let mut det =
        Detector::with_dictionary(config, dictionary_by_name("tag36h11").unwrap().clone());
    let mut out = Vec::new();
    det.detect(
        &GrayView::new(img.as_raw(), w as usize, h as usize).unwrap(),
        &mut out,
    );
    out
}

/// The reference tags some read lies within a pixel of.
fn read_within_a_pixel(out: &[Decoded], refs: &[RefTag]) -> Vec<usize> {
    (0..refs.len())
        .filter(|&i| {
            out.iter()
                .any(|d| corner_error(&d.corners, &refs[i].1) <= 1.0)
        })
        .collect()
}

#[test]
fn reads_eight_of_the_ten_reference_tags_within_a_pixel_and_nothing_false() {
    let out = detect_photo(DetectorConfig::default());
    let refs = reference();
    assert_eq!(refs.len(), 10);
    // Every tag in the photo is id 0.
    assert!(out.iter().all(|d| d.index == 0), "{out:?}");
    let read = read_within_a_pixel(&out, &refs);
    // The oblique tag the side check dropped before (the reference's seventh).
    assert!(read.contains(&6), "reference tags read: {read:?}");
    // The tag lying almost flat, which the side check dropped before (the eighth).
    assert!(read.contains(&7), "reference tags read: {read:?}");
    assert!(read.len() >= 8, "reference tags read: {read:?}");
    // The ninth, lying flat with 21 degree tips (refused by the quad fit's old 30 degrees).
    assert!(
        out.iter()
            .any(|d| corner_error(&d.corners, &refs[8].1) <= 2.5),
        "the ninth reference tag is not read"
    );
    // Every read is a tag of the photo.
    for d in &out {
        assert!(known(d, &refs), "a read at no known tag: {:?}", d.corners);
    }
}

/// With boundary clustering on (`formation-tracker detect`'s search), the third reference
/// tag is read too, within a pixel (0.56 px), and every read is a tag of the photo: a
/// reference tag within a pixel, the ninth at its 21 degree tips (2.3 px), or one of two
/// tags the reference does not list (the edge-on one on the cube, and one lying flat to the
/// right of the ninth).
#[test]
fn with_boundary_clusters_reads_the_third_tag_too() {
    let out = detect_photo(DetectorConfig {
        boundary_clusters: true,
        ..DetectorConfig::default()
    });
    let refs = reference();
    assert!(out.iter().all(|d| d.index == 0), "{out:?}");
    let read = read_within_a_pixel(&out, &refs);
    assert!(read.contains(&2), "reference tags read: {read:?}");
    assert!(read.len() >= 9, "reference tags read: {read:?}");
    for d in &out {
        assert!(known(d, &refs), "a read at no known tag: {:?}", d.corners);
    }
}

/// No false read with any other dictionary (issue #31): every name `--dictionary` accepts
/// but tag36h11's, boundary clustering on (`formation-tracker detect`'s search), reads
/// nothing on a photo whose only markers are tag36h11 tags.
#[test]
fn no_other_dictionary_reads_anything_on_the_photo() {
    let img = photo();
    let (w, h) = img.dimensions();
    let view = GrayView::new(img.as_raw(), w as usize, h as usize).unwrap();
    let detectors = common::other_dictionary_detectors("tag36h11");
    assert!(detectors.len() >= 20, "{} dictionaries", detectors.len());
    let mut out = Vec::new();
    for (name, mut det) in detectors {
        det.detect(&view, &mut out);
        assert!(out.is_empty(), "{name}: {out:?}");
    }
}
