//! Angle wrapping.

use std::f64::consts::PI;

/// Wraps an angle to `(-pi, pi]`, the convention of the spec (section 2.1).
///
/// Non-finite input is returned unchanged (NaN stays NaN) so callers that validate their
/// inputs first never see a silently invented value.
///
/// ```
/// use std::f64::consts::PI;
/// use unicycle::wrap_angle;
/// assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
/// assert_eq!(wrap_angle(-PI), PI);
/// ```
pub fn wrap_angle(a: f64) -> f64 {
    if !a.is_finite() {
        return a;
    }
    let two_pi = 2.0 * PI;
    // rem_euclid gives [0, 2pi); shift so the result is in (-pi, pi].
    let r = (a + PI).rem_euclid(two_pi) - PI;
    if r <= -PI { r + two_pi } else { r }
}
