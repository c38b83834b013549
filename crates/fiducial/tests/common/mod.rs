//! Scene helpers shared by the detector's integration tests and its benchmark (which
//! includes this file by path): the paper dictionary as `marker_testkit` patterns, and the
//! rule that keeps real markers out of clutter frames.
#![allow(dead_code)] // each test binary uses its own subset

use fiducial::Dictionary;
use marker_testkit::{CellPattern, NotMarkers};

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

/// A detector for every dictionary name `--dictionary` accepts, except those naming the
/// same dictionary as `except`, with boundary clustering on (the widest search,
/// `formation-tracker detect`'s): for the "no false read with any family" tests on real
/// frames.
pub fn other_dictionary_detectors(except: &str) -> Vec<(&'static str, fiducial::Detector)> {
    let skip = fiducial::dictionary_by_name(except).ok();
    fiducial::dictionary_names()
        .filter_map(|name| {
            let dict = fiducial::dictionary_by_name(name).ok()?;
            (Some(dict) != skip).then(|| {
                let config = fiducial::DetectorConfig {
                    boundary_clusters: true,
                    ..fiducial::DetectorConfig::default()
                };
                (
                    name,
                    fiducial::Detector::with_dictionary(config, dict.clone()),
                )
            })
        })
        .collect()
}
