//! Angle wrapping.

use std::f64::consts::{PI, TAU};

/// Wraps an angle to `(-pi, pi]`, the convention of the spec (section 2.1).
///
/// Angles already in `(-pi, pi]` come back bit for bit; `-pi` becomes `pi`. A non-finite
/// input (NaN or infinite) gives NaN, so a bad value is never turned into a plausible angle.
/// `dukf` keeps an identical copy (so that neither leaf crate depends on the other); both are
/// tested with the same cases.
///
/// ```
/// use std::f64::consts::{PI, TAU};
/// use unicycle::wrap_angle;
/// assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
/// assert_eq!(wrap_angle(-PI), PI);
/// assert!(wrap_angle(f64::INFINITY).is_nan());
/// ```
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    if a > -PI && a <= PI {
        return a;
    }
    // rem_euclid gives [0, 2 pi] (2 pi itself in rare round-off cases), mapped to (-pi, pi].
    let r = a.rem_euclid(TAU);
    if r > PI { r - TAU } else { r }
}
