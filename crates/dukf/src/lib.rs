//! A generic unscented Kalman filter, and the dual filter built from two of them, over
//! nalgebra static dimensions. This crate knows nothing about robots, cameras or formations:
//! it filters vectors through functions it is given.
//!
//! # What is here
//!
//! - [`Ukf`]: an unscented Kalman filter with additive noise: [`Ukf::predict`] (`f`, `Q`)
//!   and [`Ukf::update`] (`y`, `h`, `R`, with `R` free to change every call). A frame with no
//!   measurement is just a `predict` (the covariance grows).
//! - [`DualUkf`]: Wan and van der Merwe's dual estimation (spec section 5): a state filter
//!   over `x` with the parameters `w` held at their estimate, and a parameter filter over `w`
//!   as a random walk observing the same `y` through `g(w) = h(f(x^_{k-1}, w))`.
//!   [`DualUkf::step`] for a frame with a measurement, [`DualUkf::predict_only`] without.
//! - [`Imm`]: the interacting multiple-model filter (Blom and Bar-Shalom) over `K`
//!   unscented filters sharing one state, the models (`f(j, x)`, `Q_j`) supplied by the
//!   caller; [`sojourn_transition`] builds its switching matrix from a mean sojourn time.
//! - [`RtsSmoother`]: the unscented Rauch-Tung-Striebel smoother (Särkkä 2008) that runs
//!   backwards over a finished forward pass's filtered estimates ([`Gaussian`]), recomputing
//!   each prediction from the filtered sigma points; see its module for the equations and
//!   how to smooth a dual filter's state and parameters together.
//! - Innovation tests, before a measurement is applied: [`innovation_nis`] (how far a
//!   candidate lies from the prediction), [`Gate`] with [`GateRuns`] (accept or refuse, and
//!   when refusals in a row call for restarting the filter) and [`NoiseScale`] (a factor on
//!   `R` learned from the innovations, for errors the reported `R` does not know).
//! - [`Space`]: how to subtract, add and average vectors, with [`Euclidean`] and
//!   [`AngleMask`] ready-made; [`wrap_angle`] and [`circular_mean`] as free functions.
//! - [`unscented_transform`]: one transform on its own; [`Weights`] and [`SigmaPoints`] for
//!   those who want to look inside.
//! - [`UkfError`]: the one error type; [`JitterPolicy`] and [`factor_repaired`]: the
//!   documented covariance repair.
//!
//! # The scaled unscented transform
//!
//! For a vector of dimension `L`, `2L + 1` sigma points `x`, `x (+) gamma S_j`,
//! `x (+) (-gamma S_j)` (`S` the lower Cholesky factor of `P`, `gamma = sqrt(L + lambda)`),
//! with `lambda = a^2 (L + kappa) - L`, `W0_m = lambda / (L + lambda)`,
//! `W0_c = W0_m + (1 - a^2 + b)`, `Wi_m = Wi_c = 1 / (2 (L + lambda))`. The weights are
//! computed once, when a filter is built ([`Weights::new`]); [`UtParams::default`] is
//! `a = 0.1`, `b = 2`, `kappa = 0` (see [`UtParams`] for why not the often quoted `1e-3`).
//! Means are computed as `Y_0 + sum_{i>0} W_i (Y_i (-) Y_0)` (equal to `sum W_i Y_i` since
//! the weights sum to one) so that the large negative `W0_m` of a small `a` (about
//! `-L / a^2`) does not cancel catastrophically.
//!
//! The update redraws sigma points from the predicted estimate, so that `h` sees the
//! additive `Q`; with this, for linear `f` and `h` the filter is exactly the linear Kalman
//! filter (a property test checks it to `1e-9`).
//!
//! # Why static dimensions
//!
//! Every vector and matrix is an nalgebra `SVector<f64, N>` / `SMatrix<f64, R, C>` with the
//! dimensions as const generics. The compiler checks that `f` maps `N` to `N` and `h` maps
//! `N` to `M`; everything lives on the stack, so a step allocates nothing (an integration
//! test counts allocations to prove it), and the small fixed-size loops unroll. The `2L + 1`
//! sigma points cannot be an array (`[_; 2 * L + 1]` needs generic const expressions, which
//! are unstable), so a [`SigmaPoints`] set is a centre plus a `D x L` matrix of plus-side
//! points and one of minus-side points.
//!
//! # Why the caller supplies the mean and residual
//!
//! A filter whose state holds angles must subtract them modulo `2 pi` and average them on
//! the circle, or a heading that crosses `pi` makes the innovation `2 pi` and the mean of
//! sigma points at `pi - e` and `-pi + e` comes out `0`, the opposite direction. Only the
//! caller knows which components are angles (or quaternions, or anything else), so the
//! filter asks a [`Space`] for `residual(a, b)`, `add(x, d)` and `weighted_mean(points,
//! weights)` and never does arithmetic on states or measurements itself. [`AngleMask`]
//! covers the usual case (some components are angles): residuals and sums wrapped to
//! `(-pi, pi]`, angle means the weighted intrinsic mean on the circle seeded at the centre
//! sigma point: one fixed-point step `m = c + sum W_i wrap(theta_i - c)` when no point ends
//! up more than `pi` from the result (the usual case, checked), iterated otherwise; it stays
//! accurate for huge mixed-sign weights, where sums of sines and cosines cancel badly.
//!
//! # The jitter policy
//!
//! A covariance can lose positive definiteness to rounding (`P- - K S K^T` subtracts two
//! nearly equal matrices). The filter keeps every covariance together with its Cholesky
//! factor, and every covariance it produces goes through [`factor_repaired`]: symmetrise,
//! try Cholesky, and on failure add `j I` with `j` growing from `1e-12` by factors of 10 up
//! to `1e-6` (relative to the largest diagonal entry; see [`JitterPolicy`]). The jitter
//! actually added is returned in [`PredictReport`] / [`UpdateReport`]; if the bound is
//! reached the operation fails with [`UkfError::NotPositiveDefinite`]. The bound is small
//! on purpose: it absorbs rounding, not a noise matrix that is wrong.
//!
//! # Bad input
//!
//! A non-finite measurement, `R`, `Q`, initial state or covariance is rejected with a typed
//! [`UkfError`] before any work; a process or measurement function returning a non-finite
//! value at any sigma point is a [`UkfError::NonFiniteFunction`] naming the point and
//! component. Every operation computes on copies and commits only on success, so after an
//! error the filter holds exactly what it held before: never a NaN state.
//!
//! # Dual estimation
//!
//! The dual filter estimates unknown parameters `w` of the process (in the formation tracker
//! the leader's velocities) alongside the state: see [`DualUkf`]. Both filters read only the
//! previous estimates and are committed together. Known inputs (the follower's own
//! velocities) are captured by the caller's closure `f(x, w)`, so the filter's signature does
//! not depend on them. A model that can fail (a singular configuration) should return a
//! non-finite vector from the closure: the step then fails with
//! [`UkfError::NonFiniteFunction`] and neither filter changes.
//!
//! The parameter filter sees `w` only through one step of the model, `h(f(x^, w))`, so a
//! parameter that moves `y` only after two steps (a turn rate when only positions are
//! measured) is not observable to it. In the formation model every parameter reaches `y` in
//! one step (`l12'` depends on `v1`, `alpha12'` on `w1`).
//!
//! ```
//! use dukf::{AngleMask, DualUkf, Euclidean, Ukf, UtParams};
//! use nalgebra::{Matrix1, Vector1};
//!
//! // A heading theta turning at an unknown rate w: theta' = theta + w dt, theta measured.
//! let dt = 0.1;
//! let angles = AngleMask::new([true]);
//! let state = Ukf::new(Vector1::new(0.0), Matrix1::new(0.1), angles, UtParams::default())?;
//! let params = Ukf::new(Vector1::new(0.0), Matrix1::new(1.0), Euclidean, UtParams::default())?;
//! let mut dual = DualUkf::new(state, params, Matrix1::new(1e-6), Matrix1::new(1e-6), angles)?;
//! let mut truth = 0.0_f64;
//! for _ in 0..100 {
//!     truth = dukf::wrap_angle(truth + 0.5 * dt);
//!     dual.step(
//!         |x: &Vector1<f64>, w: &Vector1<f64>| Vector1::new(x[0] + w[0] * dt),
//!         |x: &Vector1<f64>| *x,
//!         &Vector1::new(truth),
//!         &Matrix1::new(1e-4),
//!     )?;
//! }
//! assert!((dual.parameters()[0] - 0.5).abs() < 0.05);
//! # Ok::<(), dukf::UkfError>(())
//! ```
#![deny(missing_docs)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

mod dual;
mod error;
mod gate;
mod imm;
mod jitter;
mod linearise;
mod sigma;
pub mod smoother;
mod space;
mod transform;
mod ukf;

pub use dual::{DualPredictReport, DualReport, DualUkf};
pub use error::{Covariance, DualFilter, Function, Input, UkfError};
pub use gate::{Gate, GateRuns, NoiseScale, innovation_nis};
pub use imm::{Imm, ImmReport, mixture_mean, mixture_noise, sojourn_transition};
pub use jitter::{Factored, JitterPolicy, factor_repaired};
pub use linearise::{central_jacobian, propagate_linearised};
pub use sigma::{SigmaPoints, UtParams, Weights};
pub use smoother::{Gaussian, Measured, RtsSmoother, Smoothed, filter_and_smooth};
pub use space::{AngleMask, Euclidean, Space, circular_mean, wrap_angle};
pub use transform::{Transformed, unscented_transform};
pub use ukf::{PredictReport, Ukf, UpdateReport};
