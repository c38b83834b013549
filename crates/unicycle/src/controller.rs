//! A separation-bearing formation controller for the follower.
//!
//! This is the `l-psi` controller of Das, Fierro, Kumar, Ostrowski, Spletzer and Taylor,
//! "A vision-based formation control framework", IEEE Transactions on Robotics and
//! Automation 18(5), 2002, section IV: input-output feedback linearisation of the separation
//! and the bearing in the leader's frame, made possible by the offset `d` between the
//! follower's wheel axle and the point it controls (here the camera, spec 2.2). In this
//! crate's variables (spec 2.3-2.4) the outputs are `l12` and `alpha12` (Das et al.'s `psi12`
//! is the same bearing measured from the leader's heading, up to a constant `pi`).
//!
//! From spec 2.4,
//!
//! ```text
//! [l12'    ]   [ v1 cos(alpha12)              ]       [v2]
//! [alpha12'] = [ -v1 sin(alpha12)/l12 - w1    ] + G * [w2],
//!
//! G = [ -cos(beta12)       -d sin(beta12)       ]
//!     [  sin(beta12)/l12   -d cos(beta12)/l12   ],   det G = d / l12,
//! ```
//!
//! so for `d > 0` the inputs `[v2, w2] = G^-1 (r - drift)` give the linear closed loop
//! `l12' = k_l (l12_d - l12)`, `alpha12' = k_alpha wrap(alpha12_d - alpha12)`. The remaining
//! (internal) dynamics is the relative heading `beta12`; Das et al. show it is stable when
//! the leader moves forward (`v1 > 0`) with `d > 0`, which is the case in our scenarios.
//!
//! Optional saturation clamps `|v2|` and `|w2|` after the linearising law; while a limit is
//! active the closed loop is no longer exactly linear (a documented, deliberate trade-off for
//! real wheels).

use crate::angle::wrap_angle;
use crate::error::{UnicycleError, check_finite};
use crate::polar::{Formation, MIN_SEPARATION};
use crate::robot::Inputs;

/// Gains, set-points and optional limits of the [`SeparationBearingController`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerConfig {
    /// Desired separation `l12`, metres (> 0).
    pub l12_desired: f64,
    /// Desired bearing `alpha12` in the leader's frame, radians.
    pub alpha12_desired: f64,
    /// Convergence rate of the separation error, 1/s (> 0).
    pub k_l: f64,
    /// Convergence rate of the bearing error, 1/s (> 0).
    pub k_alpha: f64,
    /// Optional limit on `|v2|`, m/s (> 0 when set).
    pub max_v: Option<f64>,
    /// Optional limit on `|w2|`, rad/s (> 0 when set).
    pub max_w: Option<f64>,
}

impl ControllerConfig {
    /// Holds `formation`'s `l12` and `alpha12` with unit gains and no saturation.
    pub fn hold(formation: &Formation) -> Self {
        Self {
            l12_desired: formation.l12,
            alpha12_desired: formation.alpha12,
            k_l: 1.0,
            k_alpha: 1.0,
            max_v: None,
            max_w: None,
        }
    }

    /// These settings after a set-point change: the new `l12` and `alpha12` where given,
    /// the old ones where `None`.
    pub fn with_setpoints(self, l12: Option<f64>, alpha12: Option<f64>) -> Self {
        Self {
            l12_desired: l12.unwrap_or(self.l12_desired),
            alpha12_desired: alpha12.unwrap_or(self.alpha12_desired),
            ..self
        }
    }
}

/// The follower's separation-bearing (`l-psi`) controller; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeparationBearingController {
    d: f64,
    config: ControllerConfig,
}

fn positive(name: &'static str, value: f64) -> Result<(), UnicycleError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(UnicycleError::InvalidControllerSetting { name, value })
    }
}

impl SeparationBearingController {
    /// A controller for a follower whose camera sits `d > 0` metres ahead of its axle.
    ///
    /// # Errors
    /// [`UnicycleError::ControllerNeedsOffset`] when `d` is not finite and positive;
    /// [`UnicycleError::InvalidControllerSetting`] for a non-positive or non-finite gain,
    /// set-point separation or limit; [`UnicycleError::NonFinite`] for a non-finite bearing.
    pub fn new(d: f64, config: ControllerConfig) -> Result<Self, UnicycleError> {
        if !(d.is_finite() && d > 0.0) {
            return Err(UnicycleError::ControllerNeedsOffset { d });
        }
        positive("l12_desired", config.l12_desired)?;
        if config.l12_desired <= MIN_SEPARATION {
            return Err(UnicycleError::SeparationTooSmall {
                l12: config.l12_desired,
                min: MIN_SEPARATION,
            });
        }
        check_finite("alpha12_desired", &[config.alpha12_desired])?;
        positive("k_l", config.k_l)?;
        positive("k_alpha", config.k_alpha)?;
        if let Some(v) = config.max_v {
            positive("max_v", v)?;
        }
        if let Some(w) = config.max_w {
            positive("max_w", w)?;
        }
        Ok(Self { d, config })
    }

    /// The configuration in use.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// Follower inputs `(v2, w2)` for the current formation variables and the leader's
    /// velocities `(v1, w1)`.
    ///
    /// # Errors
    /// Non-finite formation variables or leader inputs; `l12 <= MIN_SEPARATION`.
    pub fn inputs(&self, formation: &Formation, leader: Inputs) -> Result<Inputs, UnicycleError> {
        check_finite(
            "formation",
            &[formation.l12, formation.alpha12, formation.beta12],
        )?;
        leader.check("leader inputs")?;
        let l = formation.l12;
        if l <= MIN_SEPARATION {
            return Err(UnicycleError::SeparationTooSmall {
                l12: l,
                min: MIN_SEPARATION,
            });
        }
        let c = &self.config;
        let (sa, ca) = formation.alpha12.sin_cos();
        let (sb, cb) = formation.beta12.sin_cos();
        // Desired output rates minus the leader-driven drift.
        let r1 = c.k_l * (c.l12_desired - l) - leader.v * ca;
        let r2 = c.k_alpha * wrap_angle(c.alpha12_desired - formation.alpha12)
            + leader.v * sa / l
            + leader.w;
        // G^-1 = [[-cos b, l sin b], [-sin b / d, -l cos b / d]].
        let mut v2 = -cb * r1 + l * sb * r2;
        let mut w2 = (-sb * r1 - l * cb * r2) / self.d;
        if let Some(max) = c.max_v {
            v2 = v2.clamp(-max, max);
        }
        if let Some(max) = c.max_w {
            w2 = w2.clamp(-max, max);
        }
        Ok(Inputs::new(v2, w2))
    }
}
