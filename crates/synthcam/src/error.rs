//! The crate's single error type.

/// Everything that can go wrong when building a scene, a camera or rendering a frame.
///
/// Every variant carries the offending values so the message says what to fix.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// A number that must be finite (a pose, a size, a grey level, ...) is NaN or infinite.
    #[error("{what} must be finite, got {value}")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A length, coordinate or angle is larger in magnitude than [`crate::MAX_MAGNITUDE`] (or a
    /// `K` entry larger than [`crate::MAX_INTRINSIC`]): such values make the projection
    /// overflow, so they are refused rather than silently producing infinities.
    #[error("{what} has magnitude {value}, above the limit {max}")]
    TooLarge {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// The limit.
        max: f64,
    },
    /// A size or distance that must be strictly positive is not.
    #[error("{what} must be > 0, got {value}")]
    NotPositive {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A standard deviation (noise, blur) is negative.
    #[error("{what} must be >= 0, got {value}")]
    NegativeSigma {
        /// Which sigma.
        what: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A value that must lie in a closed range does not.
    #[error("{what} must lie in [{min}, {max}], got {value}")]
    OutOfRange {
        /// Which quantity.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// The intrinsic matrix K is not an upper-triangular pinhole matrix with positive focal
    /// lengths and `K[2][2] = 1`, or it is (numerically) singular.
    #[error("invalid intrinsic matrix K: {reason}")]
    InvalidIntrinsics {
        /// What is wrong with K.
        reason: &'static str,
    },
    /// The image has zero width or height.
    #[error("image size must be non-zero, got {width} x {height}")]
    ZeroImageSize {
        /// Requested width in pixels.
        width: usize,
        /// Requested height in pixels.
        height: usize,
    },
    /// The image is larger than [`crate::MAX_PIXELS`].
    #[error("image of {width} x {height} pixels exceeds the limit of {max} pixels")]
    ImageTooLarge {
        /// Requested width in pixels.
        width: usize,
        /// Requested height in pixels.
        height: usize,
        /// The limit.
        max: usize,
    },
    /// Supersampling factor outside `1..=MAX_SUPERSAMPLING`.
    #[error("supersampling must be 1..={max} samples per pixel side, got {n}")]
    InvalidSupersampling {
        /// Requested samples per pixel side.
        n: usize,
        /// The limit.
        max: usize,
    },
    /// A motion-blurred exposure cannot be rendered ([`crate::render_exposure`]).
    #[error("invalid exposure: {reason}")]
    InvalidExposure {
        /// What is wrong.
        reason: &'static str,
    },
    /// A texture's data does not match its declared size.
    #[error("invalid texture: {reason} ({rows} x {cols} declared, {len} values given)")]
    InvalidTexture {
        /// What is wrong.
        reason: &'static str,
        /// Declared rows (or height).
        rows: usize,
        /// Declared columns (or width).
        cols: usize,
        /// Number of values supplied.
        len: usize,
    },
    /// Degenerate geometry: a zero normal, an up vector parallel to the normal, a camera
    /// looking along its own up vector, ...
    #[error("degenerate geometry: {what}")]
    DegenerateGeometry {
        /// What is degenerate.
        what: &'static str,
    },
    /// A robot index that does not exist in the scene.
    #[error("robot index {index} out of range (scene has {len} robots)")]
    NoSuchRobot {
        /// The index asked for.
        index: usize,
        /// Number of robots.
        len: usize,
    },
    /// Writing an image failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// Largest magnitude accepted for any length (m), coordinate (m) or angle (rad) in a scene,
/// camera or setting: one thousand kilometres is far beyond any robot scene, and the bound keeps
/// every projection finite.
pub const MAX_MAGNITUDE: f64 = 1e6;

/// Largest magnitude accepted for an entry of the intrinsic matrix `K` (pixels).
pub const MAX_INTRINSIC: f64 = 1e9;

/// Check that `value` is finite and at most `max` in magnitude.
pub(crate) fn bounded(what: &'static str, value: f64, max: f64) -> Result<f64, SynthError> {
    if !value.is_finite() {
        Err(SynthError::NonFinite { what, value })
    } else if value.abs() > max {
        Err(SynthError::TooLarge { what, value, max })
    } else {
        Ok(value)
    }
}

/// Check that `value` is finite and at most [`MAX_MAGNITUDE`] in magnitude.
pub(crate) fn finite(what: &'static str, value: f64) -> Result<f64, SynthError> {
    bounded(what, value, MAX_MAGNITUDE)
}

/// Check that `value` is finite and strictly positive.
pub(crate) fn positive(what: &'static str, value: f64) -> Result<f64, SynthError> {
    finite(what, value)?;
    if value > 0.0 {
        Ok(value)
    } else {
        Err(SynthError::NotPositive { what, value })
    }
}

/// Check that `value` is finite and lies in `[min, max]`.
pub(crate) fn in_range(
    what: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<f64, SynthError> {
    finite(what, value)?;
    if (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(SynthError::OutOfRange {
            what,
            value,
            min,
            max,
        })
    }
}

/// Check that every component of a vector is finite.
pub(crate) fn finite_vec(what: &'static str, v: &nalgebra::Vector3<f64>) -> Result<(), SynthError> {
    for &c in v.iter() {
        finite(what, c)?;
    }
    Ok(())
}
