//! The crate's one error type.

/// Everything that can go wrong in this crate.
///
/// Each variant carries the offending values so a caller can log or act on them. The polar
/// model is singular only at `l12 = 0`; every other variant is bad input (non-finite numbers,
/// a non-positive time step, a negative camera offset, an unusable controller setting).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum UnicycleError {
    /// The separation `l12` is at or below [`MIN_SEPARATION`](crate::MIN_SEPARATION): the
    /// leader sits (almost) on the follower's camera and the bearings are undefined.
    #[error(
        "separation l12 = {l12} m is at or below the minimum {min} m: the polar model is \
         singular when the leader sits on the follower's camera"
    )]
    SeparationTooSmall {
        /// The separation that was found (possibly at an intermediate integration stage).
        l12: f64,
        /// The smallest separation the model accepts.
        min: f64,
    },
    /// A number in an input, a state or a result is NaN or infinite.
    #[error("non-finite {what}[{index}] = {value}: every input and state must be finite")]
    NonFinite {
        /// Which quantity: `"state"`, `"leader inputs"`, `"pose"`, ...
        what: &'static str,
        /// Component index within that quantity.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The integration step is not a finite positive number.
    #[error("time step dt = {dt} s must be finite and positive")]
    InvalidTimeStep {
        /// The step that was given.
        dt: f64,
    },
    /// The camera offset is negative or not finite.
    #[error("camera offset d = {d} m must be finite and non-negative")]
    InvalidOffset {
        /// The offset that was given.
        d: f64,
    },
    /// The formation controller needs a strictly positive camera offset: with `d = 0` the
    /// input-output map from `(v2, w2)` to `(l12', alpha12')` is singular.
    #[error(
        "the separation-bearing controller needs a camera offset d > 0 (got d = {d} m): \
         with d = 0 the follower's inputs cannot steer the bearing independently"
    )]
    ControllerNeedsOffset {
        /// The offset that was given.
        d: f64,
    },
    /// An actuation setting is out of range: a scale outside `(0, 2]` or a negative noise
    /// deviation.
    #[error(
        "actuation setting {name} = {value} is out of range: a scale is in (0, 2], a noise \
         standard deviation is at least 0"
    )]
    InvalidActuation {
        /// Which setting (`scale[0]`, `noise_std[1]`, ...).
        name: &'static str,
        /// The value that was given.
        value: f64,
    },
    /// A controller gain or saturation limit is not finite and positive.
    #[error("controller setting {name} = {value} must be finite and positive")]
    InvalidControllerSetting {
        /// Which setting.
        name: &'static str,
        /// The value that was given.
        value: f64,
    },
}

/// Returns a [`UnicycleError::NonFinite`] for the first non-finite entry of `values`.
pub(crate) fn check_finite(what: &'static str, values: &[f64]) -> Result<(), UnicycleError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(UnicycleError::NonFinite {
            what,
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

/// Checks that `dt` is finite and positive.
pub(crate) fn check_dt(dt: f64) -> Result<(), UnicycleError> {
    if dt.is_finite() && dt > 0.0 {
        Ok(())
    } else {
        Err(UnicycleError::InvalidTimeStep { dt })
    }
}
