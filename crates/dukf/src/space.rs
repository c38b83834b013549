//! The spaces a filter works in: how to subtract, add and average points.
//!
//! A Kalman filter only ever needs three operations on its vectors, and a space that is not a
//! plain vector space (one with angles in it) must supply all three:
//!
//! - [`residual(a, b)`](Space::residual), the difference `a (-) b` (angle components wrapped
//!   to `(-pi, pi]`, so that `pi - e` and `-pi + e` are `2e` apart, not `2 pi - 2e`);
//! - [`add(x, d)`](Space::add), `x (+) d` (angle components wrapped);
//! - [`weighted_mean(points, weights)`](Space::weighted_mean) of a sigma-point set (angle
//!   components averaged on the circle).
//!
//! Two ready spaces: [`Euclidean`] and [`AngleMask`] (a per-component flag saying which
//! components are angles).

use core::f64::consts::{PI, TAU};

use nalgebra::{Const, Matrix, RawStorage, SMatrix, SVector, U1};

use crate::error::UkfError;
use crate::sigma::{SigmaPoints, Weights};

/// The operations a filter needs on the vectors of one space (dimension `D`).
///
/// Implementations must satisfy, for points close enough together (for angles: less than
/// `pi` apart), `add(b, residual(a, b)) == a` and `residual(a, a) == 0`, and the weighted
/// mean must equal the ordinary weighted mean whenever the points fit in one chart.
pub trait Space<const D: usize> {
    /// `a (-) b`: the difference of two points, as a tangent vector.
    fn residual(&self, a: &SVector<f64, D>, b: &SVector<f64, D>) -> SVector<f64, D>;

    /// `x (+) d`: the point reached from `x` by the tangent vector `d`.
    fn add(&self, x: &SVector<f64, D>, d: &SVector<f64, D>) -> SVector<f64, D>;

    /// The mean of a sigma-point set under the transform's mean weights
    /// ([`Weights::mean0`] for the centre, [`Weights::other`] for the rest; they sum to one,
    /// and `mean0` may be large and negative).
    fn weighted_mean<const L: usize>(
        &self,
        points: &SigmaPoints<D, L>,
        weights: &Weights,
    ) -> SVector<f64, D>;
}

impl<const D: usize, S: Space<D>> Space<D> for &S {
    fn residual(&self, a: &SVector<f64, D>, b: &SVector<f64, D>) -> SVector<f64, D> {
        (**self).residual(a, b)
    }

    fn add(&self, x: &SVector<f64, D>, d: &SVector<f64, D>) -> SVector<f64, D> {
        (**self).add(x, d)
    }

    fn weighted_mean<const L: usize>(
        &self,
        points: &SigmaPoints<D, L>,
        weights: &Weights,
    ) -> SVector<f64, D> {
        (**self).weighted_mean(points, weights)
    }
}

/// Plain `R^D`: residual is subtraction, add is addition, the mean is the weighted sum.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Euclidean;

impl<const D: usize> Space<D> for Euclidean {
    fn residual(&self, a: &SVector<f64, D>, b: &SVector<f64, D>) -> SVector<f64, D> {
        a - b
    }

    fn add(&self, x: &SVector<f64, D>, d: &SVector<f64, D>) -> SVector<f64, D> {
        x + d
    }

    fn weighted_mean<const L: usize>(
        &self,
        points: &SigmaPoints<D, L>,
        weights: &Weights,
    ) -> SVector<f64, D> {
        // sum_i W_i Y_i == Y_0 + sum_{i>0} W_i (Y_i - Y_0) since the weights sum to one; the
        // second form avoids the cancellation between a large negative W_0 and the rest.
        let c = &points.center;
        let mut acc = SVector::<f64, D>::zeros();
        for j in 0..L {
            acc += points.plus.column(j) - c;
            acc += points.minus.column(j) - c;
        }
        c + acc * weights.other
    }
}

/// `R^D` in which some components are angles (radians), flagged per component.
///
/// Angle components have wrapped residuals and sums (to `(-pi, pi]`) and circular means;
/// the others behave as in [`Euclidean`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AngleMask<const D: usize> {
    angles: [bool; D],
}

impl<const D: usize> AngleMask<D> {
    /// A mask from one flag per component (`true` = angle).
    pub const fn new(angles: [bool; D]) -> Self {
        Self { angles }
    }

    /// A mask with the listed components as angles and the rest linear, for constants:
    /// `const MASK: AngleMask<3> = AngleMask::at(&[1, 2]);`. In a constant an index `>= D`
    /// fails to compile; at run time it panics, so use [`AngleMask::from_indices`] for
    /// indices that are not constants.
    pub const fn at(indices: &[usize]) -> Self {
        let mut angles = [false; D];
        let mut k = 0;
        while k < indices.len() {
            angles[indices[k]] = true;
            k += 1;
        }
        Self { angles }
    }

    /// A mask with the listed components as angles and the rest linear.
    ///
    /// # Errors
    /// [`UkfError::AngleIndexOutOfRange`] if an index is `>= D`.
    pub fn from_indices(indices: &[usize]) -> Result<Self, UkfError> {
        let mut angles = [false; D];
        for &index in indices {
            let flag = angles
                .get_mut(index)
                .ok_or(UkfError::AngleIndexOutOfRange {
                    index,
                    dimension: D,
                })?;
            *flag = true;
        }
        Ok(Self { angles })
    }

    /// The flags, one per component.
    pub const fn angles(&self) -> &[bool; D] {
        &self.angles
    }

    /// Whether component `i` is an angle (`false` past the end).
    pub fn is_angle(&self, i: usize) -> bool {
        self.angles.get(i).copied().unwrap_or(false)
    }

    /// Wraps the angle components of `x` to `(-pi, pi]`, leaving the others alone.
    pub fn normalize(&self, x: &SVector<f64, D>) -> SVector<f64, D> {
        let mut out = *x;
        for (v, &is_angle) in out.iter_mut().zip(&self.angles) {
            if is_angle {
                *v = wrap_angle(*v);
            }
        }
        out
    }
}

impl<const D: usize> Space<D> for AngleMask<D> {
    fn residual(&self, a: &SVector<f64, D>, b: &SVector<f64, D>) -> SVector<f64, D> {
        self.normalize(&(a - b))
    }

    fn add(&self, x: &SVector<f64, D>, d: &SVector<f64, D>) -> SVector<f64, D> {
        self.normalize(&(x + d))
    }

    fn weighted_mean<const L: usize>(
        &self,
        points: &SigmaPoints<D, L>,
        weights: &Weights,
    ) -> SVector<f64, D> {
        let c = &points.center;
        let w = weights.other;
        let mut mean = *c;
        for (k, &is_angle) in self.angles.iter().enumerate() {
            let ck = c[k];
            if is_angle {
                mean[k] = sigma_circular_mean(
                    ck,
                    weights.mean0,
                    w,
                    points.plus.row(k),
                    points.minus.row(k),
                );
            } else {
                let mut acc = 0.0;
                for j in 0..L {
                    acc += (points.plus[(k, j)] - ck) + (points.minus[(k, j)] - ck);
                }
                mean[k] = ck + w * acc;
            }
        }
        mean
    }
}

/// Wraps an angle to `(-pi, pi]`.
///
/// Angles already in `(-pi, pi]` come back bit for bit; `-pi` becomes `pi`. A non-finite
/// input (NaN or infinite) gives NaN (the filters reject non-finite values before they get
/// here). `unicycle::wrap_angle` is an identical copy (so that neither leaf crate depends on
/// the other); both are tested with the same cases.
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    if a > -PI && a <= PI {
        return a;
    }
    // rem_euclid gives [0, 2 pi] (2 pi itself in rare round-off cases), mapped to (-pi, pi].
    let r = a.rem_euclid(TAU);
    if r > PI { r - TAU } else { r }
}

/// The weighted circular mean of angles, `samples` being `(weight, angle)` pairs.
///
/// The result is the weighted mean on the circle (the point `m` where the weighted wrapped
/// residuals `wrap(theta_i - m)` sum to zero), seeded by the direction of the weighted sum of
/// unit vectors: samples at `pi - e` and `-pi + e` average to `pi`, not `0`. Weights are
/// normalised by their sum and may be negative (as sigma-point weights are).
///
/// Returns `None` for an empty slice, a non-finite sample, or weights summing to zero.
pub fn circular_mean(samples: &[(f64, f64)]) -> Option<f64> {
    let total: f64 = samples.iter().map(|s| s.0).sum();
    if samples.is_empty()
        || samples
            .iter()
            .any(|(w, a)| !w.is_finite() || !a.is_finite())
        || total == 0.0
        || !total.is_finite()
    {
        return None;
    }
    let (mut s, mut c, mut abs) = (0.0, 0.0, 0.0);
    for &(w, a) in samples {
        let (sin, cos) = a.sin_cos();
        s += w * sin;
        c += w * cos;
        abs += w.abs();
    }
    let first = samples.first().map_or(0.0, |x| x.1);
    // A resultant that vanishes (points spread evenly round the circle) gives no direction;
    // fall back to the first sample as the seed.
    let seed = if s.hypot(c) > 1e-12 * abs {
        s.atan2(c)
    } else {
        first
    };
    let mut rest = samples.iter().map(|&(w, a)| (w / total, a));
    let (w0, a0) = rest.next()?;
    Some(refine_weighted(seed, w0, a0, rest))
}

/// Weighted circular mean of one angle component of a sigma-point set: centre `c` (weight
/// `w0`) and the `2L` side points (weight `w` each), seeded at the centre.
///
/// This is the intrinsic (Karcher) mean on the circle, the point `m` where the weighted
/// wrapped residuals `sum_i W_i wrap(theta_i - m)` vanish, found by the fixed-point
/// iteration `m <- m + sum_i W_i wrap(theta_i - m)`. From the centre, one step is exact
/// unless a point ends up more than `pi` from the new mean (crosses its antipode); that is
/// checked from the extreme residuals of the first pass, and only then is the iteration
/// continued. Working with wrapped residuals keeps it accurate when weights are huge and of
/// mixed sign (`W0_m ~ -L/a^2` for a small `a`), where sums of sines and cosines would
/// cancel badly.
fn sigma_circular_mean<const L: usize, SP, SM>(
    c: f64,
    w0: f64,
    w: f64,
    plus: Matrix<f64, U1, Const<L>, SP>,
    minus: Matrix<f64, U1, Const<L>, SM>,
) -> f64
where
    SP: RawStorage<f64, U1, Const<L>>,
    SM: RawStorage<f64, U1, Const<L>>,
{
    let c = wrap_angle(c);
    // First step from the centre, tracking the extreme residuals (the centre's is 0).
    let (mut lo, mut hi, mut sides) = (0.0_f64, 0.0_f64, 0.0);
    for j in 0..L {
        let dp = wrap_angle(plus[j] - c);
        let dm = wrap_angle(minus[j] - c);
        let (a, b) = if dp < dm { (dp, dm) } else { (dm, dp) };
        lo = if a < lo { a } else { lo };
        hi = if b > hi { b } else { hi };
        sides += dp + dm;
    }
    let step = w * sides;
    let mut m = wrap_angle(c + step);
    if hi - step < PI && lo - step > -PI {
        return m;
    }
    for _ in 0..MAX_ITERATIONS {
        let mut sides = 0.0;
        for j in 0..L {
            sides += wrap_angle(plus[j] - m) + wrap_angle(minus[j] - m);
        }
        let step = w0 * wrap_angle(c - m) + w * sides;
        m = wrap_angle(m + step);
        if step.abs() <= TOLERANCE {
            break;
        }
    }
    m
}

const MAX_ITERATIONS: usize = 8;
const TOLERANCE: f64 = 1e-13;

fn refine_weighted<I>(seed: f64, w0: f64, a0: f64, others: I) -> f64
where
    I: Iterator<Item = (f64, f64)> + Clone,
{
    let mut m = wrap_angle(seed);
    for _ in 0..MAX_ITERATIONS {
        let mut step = w0 * wrap_angle(a0 - m);
        for (w, a) in others.clone() {
            step += w * wrap_angle(a - m);
        }
        m = wrap_angle(m + step);
        if step.abs() <= TOLERANCE {
            break;
        }
    }
    m
}

/// The residuals `Y_i (-) mean` of every point of a set, as a set.
pub(crate) fn residuals<const D: usize, const L: usize, S: Space<D>>(
    space: &S,
    points: &SigmaPoints<D, L>,
    mean: &SVector<f64, D>,
) -> SigmaPoints<D, L> {
    let mut plus = SMatrix::<f64, D, L>::zeros();
    let mut minus = SMatrix::<f64, D, L>::zeros();
    for j in 0..L {
        let p: SVector<f64, D> = points.plus.column(j).into_owned();
        plus.set_column(j, &space.residual(&p, mean));
        let q: SVector<f64, D> = points.minus.column(j).into_owned();
        minus.set_column(j, &space.residual(&q, mean));
    }
    SigmaPoints {
        center: space.residual(&points.center, mean),
        plus,
        minus,
    }
}
