//! The crate's one error type.
//!
//! Every fallible operation returns [`UkfError`]. A failed operation leaves the filter exactly
//! as it was (all work is done on copies and committed only at the end), so a caller can log
//! the error, skip the frame and carry on.

use core::fmt;

use thiserror::Error;

/// Which caller-supplied input held a non-finite value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Input {
    /// The state mean given to a constructor or setter.
    State,
    /// The state covariance given to a constructor or setter.
    StateCovariance,
    /// The additive process noise covariance `Q`.
    ProcessNoise,
    /// The additive parameter random-walk noise covariance `Rr` of the dual filter.
    ParameterNoise,
    /// The measurement `y`.
    Measurement,
    /// The additive measurement noise covariance `R`.
    MeasurementNoise,
}

impl fmt::Display for Input {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Input::State => "state mean",
            Input::StateCovariance => "state covariance",
            Input::ProcessNoise => "process noise covariance Q",
            Input::ParameterNoise => "parameter random-walk noise covariance Rr",
            Input::Measurement => "measurement y",
            Input::MeasurementNoise => "measurement noise covariance R",
        })
    }
}

/// Which caller-supplied function returned a non-finite value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Function {
    /// The process (transition) function `f`.
    Process,
    /// The measurement function `h` (or, in the parameter filter, `g(w) = h(f(x, w))`).
    Measurement,
}

impl fmt::Display for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Function::Process => "process function",
            Function::Measurement => "measurement function",
        })
    }
}

/// Which covariance could not be factorised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Covariance {
    /// The covariance given to a constructor or setter.
    Initial,
    /// The covariance after a prediction (`P- = sum Wc r r^T + Q`).
    Predicted,
    /// The innovation covariance (`S = sum Wc r r^T + R`).
    Innovation,
    /// The covariance after a measurement update (`P+ = P- - K S K^T`).
    Updated,
    /// A smoothed covariance (`Ps_k = P_k + G_k (Ps_{k+1} - P-_{k+1}) G_k^T`).
    Smoothed,
}

impl fmt::Display for Covariance {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Covariance::Initial => "initial state covariance",
            Covariance::Predicted => "predicted state covariance",
            Covariance::Innovation => "innovation covariance",
            Covariance::Updated => "updated state covariance",
            Covariance::Smoothed => "smoothed state covariance",
        })
    }
}

/// The two filters of a [`DualUkf`](crate::DualUkf).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DualFilter {
    /// The state filter over `x`.
    State,
    /// The parameter filter over `w`.
    Parameter,
}

impl fmt::Display for DualFilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DualFilter::State => "state filter",
            DualFilter::Parameter => "parameter filter",
        })
    }
}

/// Everything that can go wrong in this crate.
///
/// None of these leave a filter half-updated: on error the filter holds the estimate it held
/// before the call.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum UkfError {
    /// A vector input (state or measurement) has a NaN or infinite component.
    #[error("{input} component {index} is not finite ({value}); the filter was left unchanged")]
    NonFiniteVector {
        /// Which input.
        input: Input,
        /// Index of the first offending component.
        index: usize,
        /// Its value.
        value: f64,
    },

    /// A matrix input (a covariance) has a NaN or infinite entry.
    #[error("{input} entry ({row}, {col}) is not finite ({value}); the filter was left unchanged")]
    NonFiniteMatrix {
        /// Which input.
        input: Input,
        /// Row of the first offending entry.
        row: usize,
        /// Column of the first offending entry.
        col: usize,
        /// Its value.
        value: f64,
    },

    /// A caller-supplied function returned a NaN or infinite value at one sigma point.
    #[error(
        "the {function} returned a non-finite value ({value}) in component {component} at \
         sigma point {sigma_point}; check its domain (e.g. a division by a distance that \
         reached zero); the filter was left unchanged"
    )]
    NonFiniteFunction {
        /// Which function.
        function: Function,
        /// Index of the sigma point (0 is the centre, `1..=L` the plus side, `L+1..=2L` the
        /// minus side).
        sigma_point: usize,
        /// Index of the first offending output component.
        component: usize,
        /// Its value.
        value: f64,
    },

    /// Finite inputs produced a non-finite estimate (overflow: the covariance or the
    /// function values are too large for `f64`).
    #[error(
        "the {which} overflowed to a non-finite value; the inputs are too large for f64; \
         the filter was left unchanged"
    )]
    NonFiniteEstimate {
        /// The quantity that overflowed.
        which: Covariance,
    },

    /// A covariance was not positive definite even after the documented repair
    /// (symmetrise, then add diagonal jitter up to the policy's bound).
    #[error(
        "the {which} is not positive definite, even after symmetrising and adding diagonal \
         jitter up to {max_jitter:e}; check that the noise covariances are positive definite \
         or raise JitterPolicy::max_relative; the filter was left unchanged"
    )]
    NotPositiveDefinite {
        /// Which covariance.
        which: Covariance,
        /// The largest jitter that was tried (absolute, added to every diagonal entry).
        max_jitter: f64,
    },

    /// The scaled unscented transform parameters give no usable sigma points.
    #[error(
        "invalid unscented transform parameters alpha = {alpha}, beta = {beta}, kappa = \
         {kappa} for dimension {dimension}: {reason}"
    )]
    InvalidParameters {
        /// The spread parameter `a`.
        alpha: f64,
        /// The prior-knowledge parameter `b`.
        beta: f64,
        /// The secondary scaling parameter `kappa`.
        kappa: f64,
        /// The dimension `L` of the filtered vector.
        dimension: usize,
        /// What is wrong.
        reason: &'static str,
    },

    /// A jitter policy with a bound that is negative, not finite, or a growth factor that
    /// does not grow.
    #[error(
        "invalid jitter policy: initial_relative = {initial_relative}, growth = {growth}, \
         max_relative = {max_relative}; need 0 < initial <= max (or max = 0 to disable), \
         growth > 1, all finite"
    )]
    InvalidJitterPolicy {
        /// The first relative jitter tried.
        initial_relative: f64,
        /// The factor between tries.
        growth: f64,
        /// The largest relative jitter tried.
        max_relative: f64,
    },

    /// An angle mask named a component outside the vector.
    #[error("angle component index {index} is out of range for a vector of dimension {dimension}")]
    AngleIndexOutOfRange {
        /// The offending index.
        index: usize,
        /// The vector dimension.
        dimension: usize,
    },

    /// One of the two filters of a dual step failed; neither filter was changed.
    #[error("dual UKF {filter}: {source}")]
    Dual {
        /// Which filter failed.
        filter: DualFilter,
        /// What went wrong in it.
        #[source]
        source: Box<UkfError>,
    },

    /// The model probabilities or the switching matrix of an [`Imm`](crate::Imm) are not
    /// probabilities.
    #[error("invalid IMM model probabilities: {reason}")]
    InvalidModelProbabilities {
        /// What is wrong.
        reason: &'static str,
    },

    /// One model of an IMM step failed; no model and no probability was changed.
    #[error("IMM model {model}: {source}")]
    Imm {
        /// Index of the model that failed.
        model: usize,
        /// What went wrong in it.
        #[source]
        source: Box<UkfError>,
    },

    /// The smoother was given no filtered estimates.
    #[error("the smoother needs at least one filtered estimate; the history is empty")]
    EmptyHistory,

    /// One backward step of the smoother failed; no smoothed estimate was returned.
    #[error("smoother, backward step at estimate {step}: {source}")]
    Smoothing {
        /// Index of the estimate being smoothed (the transition `step -> step + 1`).
        step: usize,
        /// What went wrong in it.
        #[source]
        source: Box<UkfError>,
    },
}

impl UkfError {
    /// Wraps this error as coming from one filter of a dual step.
    pub(crate) fn in_dual(self, filter: DualFilter) -> Self {
        UkfError::Dual {
            filter,
            source: Box::new(self),
        }
    }

    /// Wraps this error as coming from model `model` of an IMM step.
    pub(crate) fn in_imm(self, model: usize) -> Self {
        UkfError::Imm {
            model,
            source: Box::new(self),
        }
    }

    /// The innermost error: for [`UkfError::Dual`], [`UkfError::Imm`] and
    /// [`UkfError::Smoothing`] the wrapped error, otherwise `self`.
    pub fn root(&self) -> &UkfError {
        match self {
            UkfError::Dual { source, .. }
            | UkfError::Imm { source, .. }
            | UkfError::Smoothing { source, .. } => source.root(),
            other => other,
        }
    }
}
