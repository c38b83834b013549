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
