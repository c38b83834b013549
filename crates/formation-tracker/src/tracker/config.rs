//! Tracker settings and errors.

use unicycle::PolarState;

use crate::filter::{FilterConfig, FilterDesign, FilterError, FormationFilter};

/// The 99.9 % point of a chi-square distribution with 3 degrees of freedom.
pub const CHI2_3_999: f64 = 16.266;

/// Errors of the tracker: bad frames and bad configurations. A failed call leaves the tracker
/// unchanged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackerError {
    /// A frame-level number is NaN or infinite.
    #[error("non-finite {what} = {value} in frame at t = {t} s")]
    NonFinite {
        /// Which input: `"t"`, `"v2"`, `"w2"`, `"camera mount"`.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// The frame time.
        t: f64,
    },
    /// Frame times must increase.
    #[error("frame time t = {t} s does not follow the previous frame's {previous} s")]
    TimeNotIncreasing {
        /// The previous frame's time.
        previous: f64,
        /// This frame's time.
        t: f64,
    },
    /// The frame's camera offset differs from the filter's `d`.
    #[error("camera mount offset {mount} m differs from the filter's d = {filter} m")]
    MountOffsetMismatch {
        /// The mount's offset.
        mount: f64,
        /// The filter template's `d`.
        filter: f64,
    },
    /// A configuration value is out of range.
    #[error("tracker configuration: {what} = {value} must be {expected}")]
    InvalidConfig {
        /// Which setting.
        what: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The filter template is unusable (checked at construction).
    #[error(transparent)]
    Filter(#[from] FilterError),
}

/// Tracker settings. [`TrackerConfig::reference`] gives the documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackerConfig {
    /// Template of every track's filter: `d`, `dt` and the tuning (`Q`, `Rr`, `w0`, `Pw0`,
    /// unscented parameters). Its `x0` and `tuning.p0` are replaced at each track's
    /// initialisation.
    pub filter: FilterConfig,
    /// Seconds without an accepted measurement after which a track is `lost`. Default 2 s.
    pub lost_after: f64,
    /// Mahalanobis gate `d^2` on `(l12, alpha12, beta12)`. Default [`CHI2_3_999`];
    /// `f64::INFINITY` disables gating.
    pub gate: f64,
    /// Standard deviations `[m, rad, rad]` whose squares are added to the propagated
    /// measurement covariance: a floor that keeps `R` positive definite and stands for the
    /// errors the pose covariance does not know (corner bias, calibration, mount). Default
    /// `[0.005, 0.005, 0.005]`; with the pooled corner noise (`corner_sigma_px = None`),
    /// `docs/tracking.md` measured `[1e-4, 1e-4, 1e-4]` with `relative_distance_std = 0.002`.
    pub measurement_floor_std: [f64; 3],
    /// Relative standard deviation of the measured distance `l12` from errors the pose fit's
    /// residuals cannot see (corner errors shared by a face's corners: blur, lighting
    /// gradient, quiet zones, which move the fit rather than the residual); `(s l12)^2` is
    /// added to the variance of `l12`. Default 0 (off); 0.002 is the mean distance error the
    /// detector and pose measure on the paper's scenes (`docs/paper-scenes.md`: 0.209 %).
    pub relative_distance_std: f64,
    /// Standard deviation of the leader's world pose `(x1, y1, theta1)` at initialisation
    /// (unobservable, carried along). Default 0.1.
    pub world_pose_prior_std: f64,
    /// Seconds during which a track started from a single face keeps a rival hypothesis
    /// from the other planar candidate. Default 1 s; 0 disables the rival.
    pub confirm_time: f64,
    /// A fixed corner noise, pixels, to which each pose covariance is rescaled (default
    /// `Some(0.5)`); `None` rescales to the corner noise measured from the detector's own residuals,
    /// pooled per robot over its recent solves ([`corner_noise_memory_dof`](Self::corner_noise_memory_dof)).
    /// `pose` scales its covariance `(J^T J)^-1` by a noise estimated from one solve's
    /// residual, `sigma^2 = max(SSE / (2N - 6), min_pixel_sigma^2)`; for one face (N = 4)
    /// that estimate has 2 degrees of freedom, and the floor is the top of the detector's
    /// measured range. The tracker undoes it (`SSE = N rms^2`) and uses the pooled
    /// `sum SSE / sum (2N - p)` (or `corner_sigma_px^2`) instead. `None` is not yet the
    /// default: with the small floor it needs, robot 3's track in the closed-loop chain demo
    /// diverges (`docs/tracking.md`).
    pub corner_sigma_px: Option<f64>,
    /// Memory of the pooled corner noise, in residual degrees of freedom: each solve with
    /// `n` degrees of freedom discounts the pool by `1 - n / memory`. Default 400 (about 200
    /// single-face frames, 40 two-face frames).
    pub corner_noise_memory_dof: f64,
    /// Prior of the pooled corner noise, pixels: the detector's documented figure
    /// (`docs/detector-accuracy.md`: 0.04-0.1 px; default 0.1 px, the top of that range).
    pub corner_noise_prior_px: f64,
    /// Weight of that prior in residual degrees of freedom. Default 10.
    pub corner_noise_prior_dof: f64,
    /// The pose solver's `min_pixel_sigma` (to undo its scaling). Default that of
    /// `pose::SolverOptions::default()`.
    pub solver_min_pixel_sigma: f64,
}

impl TrackerConfig {
    /// The defaults: the [reference tuning](crate::filter::FilterTuning::reference) (its
    /// `Q`, `Rr`, velocity prior `w0 = [0, 0]`, `Pw0 = I`) with the IMM design
    /// ([`FilterDesign::Imm`], the rule `reproduce dukf` uses; set `filter.tuning.design` to
    /// [`FilterDesign::Dual`] for the paper's dual UKF), `lost_after = 2 s`, gate
    /// 16.27, measurement floor 5 mm / 5 mrad, no distance term, world-pose prior 0.1, confirmation 1 s,
    /// corner noise 0.5 px (the pooled corner noise: memory 400 dof, prior 0.1 px over 10 dof).
    pub fn reference(d: f64, dt: f64) -> Self {
        let mut filter = FilterConfig::new(d, dt, PolarState::new(0.0, 0.0, 0.0, 1.0, 0.0, 0.0));
        filter.tuning.design = FilterDesign::Imm;
        Self {
            filter,
            lost_after: 2.0,
            gate: CHI2_3_999,
            measurement_floor_std: [0.005, 0.005, 0.005],
            relative_distance_std: 0.0,
            world_pose_prior_std: 0.1,
            confirm_time: 1.0,
            corner_sigma_px: Some(0.5),
            corner_noise_memory_dof: 400.0,
            corner_noise_prior_px: 0.1,
            corner_noise_prior_dof: 10.0,
            solver_min_pixel_sigma: pose::SolverOptions::default().min_pixel_sigma,
        }
    }

    pub(super) fn validate(&self) -> Result<(), TrackerError> {
        let positive = |what, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(TrackerError::InvalidConfig {
                    what,
                    value,
                    expected: "finite and positive",
                })
            }
        };
        positive("lost_after", self.lost_after)?;
        positive("world_pose_prior_std", self.world_pose_prior_std)?;
        positive("solver_min_pixel_sigma", self.solver_min_pixel_sigma)?;
        positive("corner_noise_memory_dof", self.corner_noise_memory_dof)?;
        positive("corner_noise_prior_px", self.corner_noise_prior_px)?;
        positive("corner_noise_prior_dof", self.corner_noise_prior_dof)?;
        if let Some(s) = self.corner_sigma_px {
            positive("corner_sigma_px", s)?;
        }
        if !(self.relative_distance_std.is_finite() && self.relative_distance_std >= 0.0) {
            return Err(TrackerError::InvalidConfig {
                what: "relative_distance_std",
                value: self.relative_distance_std,
                expected: "finite and non-negative",
            });
        }
        for s in self.measurement_floor_std {
            positive("measurement_floor_std", s)?;
        }
        if !(self.confirm_time.is_finite() && self.confirm_time >= 0.0) {
            return Err(TrackerError::InvalidConfig {
                what: "confirm_time",
                value: self.confirm_time,
                expected: "finite and non-negative",
            });
        }
        if self.gate.is_nan() || self.gate <= 0.0 {
            return Err(TrackerError::InvalidConfig {
                what: "gate",
                value: self.gate,
                expected: "positive (infinity disables gating)",
            });
        }
        // Builds one filter to check the template (dt, d, covariances).
        FormationFilter::new(&self.filter)?;
        Ok(())
    }
}
