//! Factorising a covariance, with the documented repair when it has lost definiteness.
//!
//! See [`JitterPolicy`] for the procedure.

use nalgebra::{Cholesky, SMatrix};

use crate::error::{Covariance, UkfError};

/// How much diagonal jitter may be added to a covariance whose Cholesky factorisation fails.
///
/// All amounts are relative to the largest absolute diagonal entry of the matrix.
///
/// # The procedure
///
/// Every covariance the filter needs a square root of (the state covariance for sigma
/// points, the innovation covariance for the gain) goes through [`factor_repaired`]:
///
/// 1. symmetrise: `P <- (P + P^T) / 2` (always; rounding makes `P` drift from symmetric and
///    nalgebra's Cholesky reads only the lower triangle, so without this the drift would be
///    silently ignored in one half and kept in the other);
/// 2. try the Cholesky factorisation;
/// 3. if it fails, add `j I` with `j = initial_relative * s`, then `j * growth`, ... up to
///    `max_relative * s`, where `s` is the largest absolute diagonal entry (or 1 if the
///    diagonal is all zero), retrying after each addition;
/// 4. if it still fails, return [`UkfError::NotPositiveDefinite`].
///
/// The repaired matrix (with its jitter) replaces the original, so the covariance a filter
/// holds always matches the factor it uses, and the jitter actually added is reported to the
/// caller (in [`PredictReport`](crate::PredictReport) and
/// [`UpdateReport`](crate::UpdateReport)). With the default bound (`1e-6` relative) the
/// repair absorbs rounding (eigenvalues a few ulps below zero) but does not hide a
/// covariance that is wrong: a negative eigenvalue below `-1e-6` times the largest variance
/// is an error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JitterPolicy {
    /// First relative jitter tried.
    pub initial_relative: f64,
    /// Factor between successive tries (`> 1`).
    pub growth: f64,
    /// Largest relative jitter tried; `0` disables the repair (symmetrisation only).
    pub max_relative: f64,
}

impl Default for JitterPolicy {
    /// `1e-12`, growing by 10, up to `1e-6` (at most 7 retries).
    fn default() -> Self {
        Self {
            initial_relative: 1e-12,
            growth: 10.0,
            max_relative: 1e-6,
        }
    }
}

impl JitterPolicy {
    /// No jitter at all: a covariance that fails Cholesky after symmetrisation is an error.
    pub const DISABLED: Self = Self {
        initial_relative: 0.0,
        growth: 10.0,
        max_relative: 0.0,
    };

    /// Checks the policy.
    ///
    /// # Errors
    /// [`UkfError::InvalidJitterPolicy`] unless all values are finite, `growth > 1`, and
    /// either `max_relative == 0` (disabled) or `0 < initial_relative <= max_relative`.
    pub fn validate(&self) -> Result<(), UkfError> {
        let Self {
            initial_relative,
            growth,
            max_relative,
        } = *self;
        let finite = initial_relative.is_finite() && growth.is_finite() && max_relative.is_finite();
        let disabled = max_relative == 0.0 && initial_relative >= 0.0;
        let enabled = initial_relative > 0.0 && initial_relative <= max_relative;
        if finite && growth > 1.0 && (disabled || enabled) {
            Ok(())
        } else {
            Err(UkfError::InvalidJitterPolicy {
                initial_relative,
                growth,
                max_relative,
            })
        }
    }
}

/// A covariance with its lower Cholesky factor, after the repair if one was needed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Factored<const D: usize> {
    /// The (symmetrised, possibly jittered) covariance; `factor * factor^T` equals it.
    pub covariance: SMatrix<f64, D, D>,
    /// The lower-triangular Cholesky factor.
    pub factor: SMatrix<f64, D, D>,
    /// The diagonal jitter that was added (absolute; `0` if none was needed).
    pub jitter: f64,
}

/// Symmetrises `m`, factorises it, and repairs it by bounded diagonal jitter if needed.
///
/// # Errors
/// - [`UkfError::NonFiniteEstimate`] if `m` has a non-finite entry;
/// - [`UkfError::NotPositiveDefinite`] if the repair fails within the policy's bound.
pub fn factor_repaired<const D: usize>(
    m: &SMatrix<f64, D, D>,
    policy: &JitterPolicy,
    which: Covariance,
) -> Result<Factored<D>, UkfError> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err(UkfError::NonFiniteEstimate { which });
    }
    let sym = (m + m.transpose()) * 0.5;
    if let Some(ch) = Cholesky::new(sym) {
        return Ok(Factored {
            covariance: sym,
            factor: ch.unpack(),
            jitter: 0.0,
        });
    }
    let scale = sym
        .diagonal()
        .iter()
        .fold(0.0_f64, |acc, v| acc.max(v.abs()));
    let scale = if scale > 0.0 { scale } else { 1.0 };
    let max_jitter = policy.max_relative * scale;
    let mut jitter = policy.initial_relative * scale;
    // `validate` guarantees growth > 1 and initial > 0 when enabled, so this terminates; the
    // iteration cap is a second guard against a policy that skipped validation.
    let mut tries = 0;
    while max_jitter > 0.0 && jitter > 0.0 && jitter <= max_jitter * (1.0 + 1e-12) && tries < 64 {
        let mut candidate = sym;
        for i in 0..D {
            candidate[(i, i)] += jitter;
        }
        if let Some(ch) = Cholesky::new(candidate) {
            return Ok(Factored {
                covariance: candidate,
                factor: ch.unpack(),
                jitter,
            });
        }
        jitter *= policy.growth;
        tries += 1;
    }
    Err(UkfError::NotPositiveDefinite { which, max_jitter })
}
