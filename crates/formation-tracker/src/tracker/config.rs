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
    /// Measurements refused in a row, each beyond four times the gate of every IMM model's
    /// prediction, after which the track is restarted from the latest one (reported
    /// `measurement: initialised`, status `tracking`; the leader-velocity estimate is kept,
    /// with the prior's spread), instead of coasting until [`lost_after`](Self::lost_after);
    /// five times as many refused in a row restart it however near the gate they lay.
    /// Default 2; 0 never restarts. A leader that
    /// starts, stops or turns faster than every model of the filter allows (a robot at rest
    /// that reaches 0.8 m/s within one frame) is refused by the gate from then on; the
    /// restart takes it up one frame later. A single outlying frame is still refused.
    pub restart_after_gated: u32,
    /// Memory, in tested measurements, of the factor the tracker puts on each robot's `R`
    /// when the innovations are larger than `R` and the prediction say. After each
    /// measurement the gate tested (applied or refused), the factor `s` (2 before the
    /// robot's first measurement: its unseen errors are not yet known) becomes
    /// `s (1 + (min(d^2, gate) / 3 - 1) / memory)`, kept within 0.1-100, the initial 2
    /// weighing five measurements ([`dukf::NoiseScale::with_prior`]): it settles where the
    /// mean `d^2` is 3 (errors the fit residuals cannot see, such as corner errors shared by
    /// a face's corners, raise it; errors so slow that the track follows them lower it: at
    /// `far` it settles near 0.3). Default 20
    /// (two thirds of a second at 30 frames/s: chosen on the demo's seed 1 among 10, 20, 30
    /// and 100, `docs/tracking.md`); at least 1, or 0 to keep `R` as the pose covariance gives it.
    pub innovation_memory: f64,
    /// Standard deviations `[m, rad, rad]` whose squares are added to the propagated
    /// measurement covariance: a floor that keeps `R` positive definite and stands for the
    /// errors the pose covariance does not know (corner bias, calibration, mount). Default
    /// `[3e-5, 3e-5, 3e-5]` (0.03 mm, 0.03 mrad: a third of the nearest demo leader's
    /// measured error, so that `R` stays the pooled corner noise's; `docs/tracking.md`).
    /// The earlier default, `[0.005, 0.005, 0.005]`, was 50 times the vision error near the
    /// leader and made the filter 2.3 times worse than its own measurements.
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
    /// A fixed corner noise, pixels, to which each pose covariance is rescaled (`Some`), or
    /// `None` (the default) to rescale to the corner noise measured from the detector's own
    /// residuals, pooled per robot over its recent solves
    /// ([`corner_noise_memory_dof`](Self::corner_noise_memory_dof)).
    /// `pose` scales its covariance `(J^T J)^-1` by a noise estimated from one solve's
    /// residual, `sigma^2 = max(SSE / (2N - 6), min_pixel_sigma^2)`; for one face (N = 4)
    /// that estimate has 2 degrees of freedom, and the floor is the top of the detector's
    /// measured range. The tracker undoes it (`SSE = N rms^2`) and uses the pooled
    /// `sum SSE / sum (2N - p)` (or `corner_sigma_px^2`) instead.
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
    /// 16.27, a restart after 2 refused measurements in a row, `R` from the pooled corner noise (memory 400 dof, prior 0.1 px over 10 dof)
    /// with a floor of 0.03 mm / 0.03 mrad and no distance term, world-pose prior 0.1,
    /// confirmation 1 s. Two of the IMM's leader-motion settings are the tracker's own: a
    /// camera measures the formation to a tenth of a millimetre, so the held formation of
    /// model B drifts by at most 1 mm/s, 1 mrad/s (`held_rate_std`, 1 cm/s in the
    /// reference tuning) and model A's jerk is 0.2 (m/s^3, rad/s^3; 0.5 in the reference
    /// tuning), chosen on the demo's seed 1 and checked on seeds 2 and 3
    /// (`docs/tracking.md`, "Measurement noise `R` and consistency").
    pub fn reference(d: f64, dt: f64) -> Self {
        let mut filter = FilterConfig::new(d, dt, PolarState::new(0.0, 0.0, 0.0, 1.0, 0.0, 0.0));
        filter.tuning.design = FilterDesign::Imm;
        filter.tuning.imm.held_rate_std = nalgebra::Vector2::new(0.001, 0.001);
        filter.tuning.imm.jerk = nalgebra::Vector2::new(0.2, 0.2);
        Self {
            filter,
            lost_after: 2.0,
            gate: CHI2_3_999,
            restart_after_gated: 2,
            innovation_memory: 20.0,
            measurement_floor_std: [3e-5, 3e-5, 3e-5],
            relative_distance_std: 0.0,
            world_pose_prior_std: 0.1,
            confirm_time: 1.0,
            corner_sigma_px: None,
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
        if !(self.innovation_memory == 0.0
            || (self.innovation_memory.is_finite() && self.innovation_memory >= 1.0))
        {
            return Err(TrackerError::InvalidConfig {
                what: "innovation_memory",
                value: self.innovation_memory,
                expected: "0 or a finite number of at least 1",
            });
        }
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
