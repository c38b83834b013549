//! The median the diagnostic examples report over seeds.

/// The median of `v` (the mean of the two middle values for an even count); `v` must not be
/// empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    0.5 * (v[(n - 1) / 2] + v[n / 2])
}
