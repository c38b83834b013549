//! Scene helpers shared by the detector's integration tests and its benchmark (which
//! includes this file by path): the paper dictionary as `marker_testkit` patterns, and the
//! rule that keeps real markers out of clutter frames.
#![allow(dead_code)] // each test binary uses its own subset

use fiducial::Dictionary;
use marker_testkit::{CellPattern, NotMarkers};

/// Of a detection's readings `out` on `scene`: how many of the scene's markers were read,
/// and how many readings are of no marker in the scene (wrong codes).
pub fn tally(scene: &marker_testkit::MarkerScene, out: &[fiducial::Decoded]) -> (usize, usize) {
    let read = scene
        .markers
        .iter()
        .filter(|m| out.iter().any(|d| Some(d.index) == m.index))
        .count();
    let wrong = out
        .iter()
        .filter(|d| !scene.markers.iter().any(|m| m.index == Some(d.index)))
        .count();
    (read, wrong)
}

/// Every entry of `dict` as a test pattern (index = dictionary index).
pub fn entries(dict: &Dictionary) -> Vec<CellPattern> {
    let f = dict.family();
    CellPattern::from_codes(
        f.rows() as usize,
        f.cols() as usize,
        (0..dict.len()).map(|i| dict.code(i).unwrap_or(0)),
    )
}

fn paper_entry(code: u64) -> bool {
    Dictionary::paper().lookup_within(code, 0).is_some()
}

/// Clutter may not hold real entries of the paper dictionary (see `NotMarkers`).
pub fn not_markers() -> NotMarkers<'static> {
    let f = Dictionary::paper().family();
    NotMarkers {
        rows: f.rows() as usize,
        cols: f.cols() as usize,
        is_marker: &paper_entry,
    }
}

/// A detector for each distinct dictionary `--dictionary` accepts (the first of the names
/// that give the same dictionary), leaving out the one `except` names, boundary clustering
/// as asked: for the "no false read with any family" tests on real frames.
pub fn dictionary_detectors(
    boundary_clusters: bool,
    except: Option<&str>,
) -> Vec<(&'static str, fiducial::Detector)> {
    let mut seen: Vec<&Dictionary> = except
        .and_then(|name| fiducial::dictionary_by_name(name).ok())
        .into_iter()
        .collect();
    let mut v = Vec::new();
    for name in fiducial::dictionary_names() {
        let Ok(dict) = fiducial::dictionary_by_name(name) else {
            continue;
        };
        if seen.contains(&dict) {
            continue;
        }
        seen.push(dict);
        let config = fiducial::DetectorConfig {
            boundary_clusters,
            ..fiducial::DetectorConfig::default()
        };
        v.push((
            name,
            fiducial::Detector::with_dictionary(config, dict.clone()),
        ));
    }
    v
}

/// [`dictionary_detectors`] but `except`'s, with boundary clustering on (the widest search,
/// `formation-tracker detect`'s).
pub fn other_dictionary_detectors(except: &str) -> Vec<(&'static str, fiducial::Detector)> {
    dictionary_detectors(true, Some(except))
}
