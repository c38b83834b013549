//! What the dukf table and its smoothing section share: the seeds and small helpers.

/// The seeds the tables are tuned and reported on.
pub const SEEDS: std::ops::RangeInclusive<u64> = 1..=20;
/// Seeds never used for tuning, reported as a check.
pub const CHECK_SEEDS: std::ops::RangeInclusive<u64> = 21..=40;

/// The median of `v` (NaN when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// `pass` or `FAIL`.
pub fn verdict(ok: bool) -> &'static str {
    if ok { "pass" } else { "FAIL" }
}

/// Seeds the issue #30 table reports on, never used for tuning its baselines (which are tuned
/// on [`SEEDS`]).
pub const HELD_OUT_SEEDS: std::ops::RangeInclusive<u64> = 101..=120;
