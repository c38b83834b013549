//! The leader's motion as a follower can hypothesise it from its own inputs: the
//! leader velocities that hold the formation, that hold the bearing, or that let the
//! follower's separation-bearing controller achieve what it commands (spec 2.4); and one
//! prediction step of the joint state `z = [x1, y1, theta1, l12, alpha12, beta12, v1, w1,
//! a_v, a_w]` under each of three motion hypotheses ([`LeaderMotion`]), which a
//! multiple-model filter mixes.

use nalgebra::{SMatrix, SVector, Vector2, Vector3};

use crate::{ControllerConfig, PolarModel, PolarState, UnicycleError, wrap_angle};

/// The joint state `[x1, y1, theta1, l12, alpha12, beta12, v1, w1, a_v, a_w]`: the polar state,
/// the leader's velocities and their rates of change.
pub type LeaderState = SVector<f64, 10>;

/// The leader velocity `[v1, w1]` that keeps `l12` and `alpha12` constant at the state `x`
/// given the follower's inputs `u` (spec 2.4 with `l12' = alpha12' = 0`):
/// `v1 = (v2 cos(beta12) + d w2 sin(beta12)) / cos(alpha12)`,
/// `w1 = (-v1 sin(alpha12) + v2 sin(beta12) - d w2 cos(beta12)) / l12`. Non-finite when
/// `cos(alpha12) = 0` (the leader abeam: no speed holds the separation).
pub fn formation_holding_velocity(x: &PolarState, u: &Vector2<f64>, d: f64) -> Vector2<f64> {
    let (l, a, b) = (x[3], x[4], x[5]);
    let (v2, w2) = (u[0], u[1]);
    let v1 = (v2 * b.cos() + d * w2 * b.sin()) / a.cos();
    let w1 = (-v1 * a.sin() + v2 * b.sin() - d * w2 * b.cos()) / l;
    Vector2::new(v1, w1)
}

/// The leader turn rate that keeps `alpha12` constant at the state `x` given the follower's
/// inputs `u` and the leader speed `v1`: `w1 = (-v1 sin(alpha12) + v2 sin(beta12) - d w2
/// cos(beta12)) / l12` (spec 2.4 with `alpha12' = 0`).
pub fn bearing_holding_turn_rate(x: &PolarState, u: &Vector2<f64>, v1: f64, d: f64) -> f64 {
    let (l, a, b) = (x[3], x[4], x[5]);
    (-v1 * a.sin() + u[0] * b.sin() - d * u[1] * b.cos()) / l
}

/// The leader velocity `[v1, w1]` under which the follower's separation-bearing controller
/// achieves what it commands, given its inputs `u`: with `controller` (gains and set-points),
/// `l12' = k_l (l12_d - l12)` and `alpha12' = k_alpha (alpha12_d - alpha12)` (spec 2.4):
/// `v1 = (k_l (l12_d - l12) + v2 cos(beta12) + d w2 sin(beta12)) / cos(alpha12)`,
/// `w1 = (-v1 sin(alpha12) + v2 sin(beta12) - d w2 cos(beta12)) / l12 - k_alpha (alpha12_d -
/// alpha12)`; without it, [`formation_holding_velocity`] (`l12' = alpha12' = 0`).
pub fn controlled_formation_velocity(
    x: &PolarState,
    u: &Vector2<f64>,
    d: f64,
    controller: Option<ControllerConfig>,
) -> Vector2<f64> {
    let Some(c) = controller else {
        return formation_holding_velocity(x, u, d);
    };
    let (l, a, b) = (x[3], x[4], x[5]);
    let (v2, w2) = (u[0], u[1]);
    let v1 = (c.k_l * (c.l12_desired - l) + v2 * b.cos() + d * w2 * b.sin()) / a.cos();
    let w1 = (-v1 * a.sin() + v2 * b.sin() - d * w2 * b.cos()) / l
        - c.k_alpha * wrap_angle(c.alpha12_desired - a);
    Vector2::new(v1, w1)
}

/// How the leader is hypothesised to move over one step (see [`predict_leader`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeaderMotion {
    /// A: the leader accelerates: `[v1, w1]` move with `[a_v, a_w]`.
    Accelerates,
    /// B: the follower holds the formation (or, with its controller known, moves it as the
    /// controller commands): the leader velocity is [`controlled_formation_velocity`].
    HoldsFormation,
    /// C: the follower holds the bearing while its separation changes: model A's speed and
    /// the turn rate of [`bearing_holding_turn_rate`] (less the controller's bearing term).
    HoldsBearing,
    /// J, in C's place when [`LeaderMotionTuning::jump`] is set: the leader manoeuvres, its
    /// velocity jumping ([`LeaderJump::velocity_std`] per step); predicted as A.
    Jumps,
}

impl LeaderMotion {
    /// The three hypotheses in the order A, B, C.
    pub const ALL: [Self; 3] = [Self::Accelerates, Self::HoldsFormation, Self::HoldsBearing];
}

/// The separation (m) below which a state is clamped before it is propagated by
/// [`predict_leader`]; far below any real separation between two robots.
pub const MIN_PREDICTED_SEPARATION: f64 = 0.01;

/// One step of `dt` of the joint state `z` under the hypothesis `motion`, with the
/// follower's inputs `u` and, if known, its controller. A moves the formation with the
/// leader velocity `[v1, w1]` and integrates the accelerations into it; B moves it with the
/// velocity of [`controlled_formation_velocity`] and stores that velocity in `[v1, w1]`
/// (accelerations kept); C keeps A's speed but turns at the rate that holds `alpha12`.
/// Without the controller, B's `l12` and `alpha12` (C's `alpha12`) end the step where they
/// began: the holding velocity, held over the step, keeps them still only at its start,
/// while a follower that holds the formation corrects that drift at every step.
///
/// States outside the model's domain (drawn as sigma points from a wide covariance while
/// coasting) are recovered, never failed: `l12` below [`MIN_PREDICTED_SEPARATION`] is
/// clamped to it, and a step the model refuses because the separation would cross zero is
/// taken with the leader stopped, or not at all.
///
/// # Errors
/// Any other error of [`PolarModel::f`] (non-finite state or inputs).
pub fn predict_leader(
    model: &PolarModel,
    motion: LeaderMotion,
    z: &LeaderState,
    u: &Vector2<f64>,
    dt: f64,
    controller: Option<ControllerConfig>,
) -> Result<LeaderState, UnicycleError> {
    let mut x: PolarState = z.fixed_rows::<6>(0).into_owned();
    if x[3] < MIN_PREDICTED_SEPARATION {
        x[3] = MIN_PREDICTED_SEPARATION;
    }
    let w = match motion {
        LeaderMotion::Accelerates | LeaderMotion::Jumps => Vector2::new(z[6], z[7]),
        LeaderMotion::HoldsFormation => controlled_formation_velocity(&x, u, model.d(), controller),
        LeaderMotion::HoldsBearing => Vector2::new(
            z[6],
            bearing_holding_turn_rate(&x, u, z[6], model.d())
                - controller.map_or(0.0, |c| c.k_alpha * wrap_angle(c.alpha12_desired - x[4])),
        ),
    };
    // A state whose separation the step would drive through zero (a leader speed many
    // standard deviations out) is propagated with the leader stopped, so that the spread of
    // `l12` stays finite.
    let next = match model.f(&x, u, &w, dt) {
        Err(UnicycleError::SeparationTooSmall { .. }) => {
            match model.f(&x, u, &Vector2::new(0.0, w[1]), dt) {
                Err(UnicycleError::SeparationTooSmall { .. }) => Ok(x),
                other => other,
            }
        }
        other => other,
    }?;
    let mut out = *z;
    out.fixed_rows_mut::<6>(0).copy_from(&next);
    // Not told the controller, B and C hold their variables over the whole step, not only at
    // its start: a leader velocity held over the step that keeps `l12' = alpha12' = 0` at the
    // start still moves them as `beta12` turns (0.02 mm a step on the demo), a drift the
    // follower's controller corrects at the next step and the formation never shows.
    if controller.is_none() {
        match motion {
            LeaderMotion::HoldsFormation => {
                out[3] = x[3];
                out[4] = x[4];
            }
            LeaderMotion::HoldsBearing => out[4] = x[4],
            _ => {}
        }
    }
    match motion {
        LeaderMotion::Accelerates | LeaderMotion::Jumps => {
            out[6] += z[8] * dt;
            out[7] += z[9] * dt;
        }
        LeaderMotion::HoldsFormation => {
            out[6] = w[0];
            out[7] = w[1];
        }
        LeaderMotion::HoldsBearing => {
            out[6] += z[8] * dt;
            out[7] = w[1];
        }
    }
    Ok(out)
}

/// The settings of the leader-motion hypotheses as a multiple-model filter runs them: their
/// process noises, how long one stays in force and the prior of the first. Every number is a
/// property of a robot or of the simulation, none of a scenario
/// (`docs/dukf-reproduction.md`, "The IMM design").
#[derive(Debug, Clone, PartialEq)]
pub struct LeaderMotionTuning {
    /// The leader's largest jerk `[m/s^3, rad/s^3]`: model A's accelerations are a random
    /// walk with per-step standard deviation `jerk * dt`.
    pub jerk: Vector2<f64>,
    /// Standard deviation of the initial leader accelerations `[m/s^2, rad/s^2]` (mean 0).
    pub acceleration_std: Vector2<f64>,
    /// Process noise per step on `[l12, alpha12, beta12]` in both models (m^2, rad^2, rad^2):
    /// the model error of one RK4 step, not a motion.
    pub formation_q: Vector3<f64>,
    /// Models B and C ("the follower holds the formation / the bearing"): the held variables
    /// (`l12` and `alpha12` in B, `alpha12` in C) move by a random walk of per-step standard
    /// deviation `held_rate_std * dt` (m, rad), i.e. a drift of the held formation at up to
    /// about `held_rate_std` (`[m/s, rad/s]`).
    pub held_rate_std: Vector2<f64>,
    /// Process noise per step on `[l12, alpha12, beta12]` in model B while the follower's
    /// controller is known (`formation_tracker`'s `set_follower_controller`): B's prediction is
    /// then exact but for the integrator, whose error in one RK4 step is about
    /// `l12 (k dt)^5 / 120` (4e-10 m with the controller gain `k = 1 /s` at 30 Hz); this is
    /// that error rounded up, not a motion (`docs/dukf-reproduction.md`, measurement 12).
    pub controlled_formation_q: Vector3<f64>,
    /// Mean time a model stays in force, seconds (the switching matrix is
    /// `Pi_jj = exp(-dt / sojourn)`).
    pub sojourn: f64,
    /// Initial probability of model A (constant-acceleration leader); models B and C share
    /// the rest equally.
    pub mu0_a: f64,
    /// A manoeuvre hypothesis J in place of C, with the follower's controller unknown (`None`
    /// in the reference settings; issue #30, `docs/dukf-held-out.md`).
    pub jump: Option<LeaderJump>,
}

/// Hypothesis J: the leader's velocity jumps (a step of `v1`, a flip of `w1`), which a
/// constant-acceleration model with a jerk sized for smooth motion follows only slowly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeaderJump {
    /// Per-step standard deviation of the velocity jump `[m/s, rad/s]`, added to A's noise.
    pub velocity_std: Vector2<f64>,
    /// Mean time J stays in force once entered, seconds (it hands back to A).
    pub sojourn: f64,
    /// Mean time between manoeuvres, seconds (A hands over to J at `dt / onset` per step).
    pub onset: f64,
}

impl LeaderMotionTuning {
    /// The reference settings: `jerk = [0.5, 0.5]` (about twice the largest jerk of any
    /// fixture's leader), `acceleration_std = [0.2, 0.2]`, `formation_q = 1e-9` each,
    /// `held_rate_std = [0.01, 0.01]` (1 cm/s, 0.01 rad/s), `controlled_formation_q = 1e-18`
    /// each (1 nm, 1 nrad per step), `sojourn = 20 s`, `mu0_a = 0.5` (the other two models
    /// share the rest).
    pub fn reference() -> Self {
        Self {
            jerk: Vector2::new(0.5, 0.5),
            acceleration_std: Vector2::new(0.2, 0.2),
            formation_q: Vector3::new(1e-9, 1e-9, 1e-9),
            held_rate_std: Vector2::new(0.01, 0.01),
            controlled_formation_q: Vector3::new(1e-18, 1e-18, 1e-18),
            sojourn: 20.0,
            mu0_a: 0.5,
            jump: None,
        }
    }
}

impl Default for LeaderMotionTuning {
    fn default() -> Self {
        Self::reference()
    }
}

impl LeaderMotionTuning {
    /// `Ok` if every noise is finite and `mu0_a` is a probability.
    ///
    /// # Errors
    /// [`UnicycleError::NonFinite`] naming the first bad setting.
    pub fn validate(&self) -> Result<(), UnicycleError> {
        let noises = self
            .jerk
            .iter()
            .chain(self.acceleration_std.iter())
            .chain(self.formation_q.iter())
            .chain(self.held_rate_std.iter())
            .chain(self.controlled_formation_q.iter());
        if let Some((index, &value)) = noises.enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(UnicycleError::NonFinite {
                what: "leader-motion noise",
                index,
                value,
            });
        }
        if let Some(j) = &self.jump {
            let bad = j
                .velocity_std
                .iter()
                .copied()
                .chain([j.sojourn, j.onset])
                .enumerate()
                .find(|(i, v)| !v.is_finite() || *v < 0.0 || (*i >= 2 && *v <= 0.0));
            if let Some((index, value)) = bad {
                return Err(UnicycleError::NonFinite {
                    what: "leader jump (velocity_std >= 0, sojourn and onset > 0)",
                    index,
                    value,
                });
            }
        }
        if !(0.0..=1.0).contains(&self.mu0_a) {
            return Err(UnicycleError::NonFinite {
                what: "leader-motion prior mu0_a (a probability)",
                index: 0,
                value: self.mu0_a,
            });
        }
        Ok(())
    }

    /// The three hypotheses in the filter's order: A, B, and C or, with [`Self::jump`], J.
    pub fn motions(&self) -> [LeaderMotion; 3] {
        let third = if self.jump.is_some() {
            LeaderMotion::Jumps
        } else {
            LeaderMotion::HoldsBearing
        };
        [
            LeaderMotion::Accelerates,
            LeaderMotion::HoldsFormation,
            third,
        ]
    }

    /// The per-step process noises over [`LeaderState`] of the hypotheses A, B, C
    /// ([`LeaderMotion::ALL`]; J in C's place with [`Self::jump`]) for a step of `dt`, with `pose_q` the noise of the leader's
    /// pose `[x1, y1, theta1]`: with the follower's controller unknown (B and C hold the
    /// formation or the bearing up to a random walk of `held_rate_std`) and known (B follows
    /// the controller, predicted exactly but for the integrator's error
    /// `controlled_formation_q`; C, which B then covers, keeps A's noise).
    pub fn process_noises(&self, pose_q: &Vector3<f64>, dt: f64) -> [[LeaderNoise; 3]; 2] {
        let mut qa = LeaderNoise::zeros();
        for k in 0..3 {
            qa[(k, k)] = pose_q[k];
            qa[(3 + k, 3 + k)] = self.formation_q[k];
        }
        qa[(8, 8)] = (self.jerk[0] * dt).powi(2);
        qa[(9, 9)] = (self.jerk[1] * dt).powi(2);
        let mut qb = qa;
        qb[(3, 3)] += (self.held_rate_std[0] * dt).powi(2);
        qb[(4, 4)] += (self.held_rate_std[1] * dt).powi(2);
        let mut qc = qa;
        match &self.jump {
            Some(j) => {
                qc[(6, 6)] += j.velocity_std[0].powi(2);
                qc[(7, 7)] += j.velocity_std[1].powi(2);
            }
            None => qc[(4, 4)] += (self.held_rate_std[1] * dt).powi(2),
        }
        let mut qb_controlled = qa;
        for k in 0..3 {
            qb_controlled[(3 + k, 3 + k)] = self.controlled_formation_q[k];
        }
        [[qa, qb, qc], [qa, qb_controlled, qa]]
    }
}

/// A process noise over [`LeaderState`].
pub type LeaderNoise = SMatrix<f64, 10, 10>;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn holding_velocities_hold_the_formation() {
        // Through the model: with the holding velocity, l12' = alpha12' = 0.
        let model = PolarModel::new(0.5).unwrap();
        let x = PolarState::from_row_slice(&[1.5, 0.25, 0.3, 1.2, 0.3, -0.2]);
        let u = Vector2::new(0.7, 0.15);
        let w = formation_holding_velocity(&x, &u, 0.5);
        let dx = model.derivative(&x, &u, &w).unwrap();
        assert!(dx[3].abs() < 1e-12 && dx[4].abs() < 1e-12, "{dx:?}");
        let w1 = bearing_holding_turn_rate(&x, &u, 0.9, 0.5);
        let dx = model.derivative(&x, &u, &Vector2::new(0.9, w1)).unwrap();
        assert!(dx[4].abs() < 1e-12 && dx[3].abs() > 0.1, "{dx:?}");
    }

    #[test]
    fn held_variables_end_the_step_where_they_began() {
        // Regression (issue #30): B held l12 and alpha12 only at the start of the step; with
        // the holding velocity held over it they drifted as beta12 turned (tens of um a step
        // on the demo), a bias the follower's controller does not have.
        let model = PolarModel::new(0.5).unwrap();
        let mut z = LeaderState::zeros();
        z.fixed_rows_mut::<6>(0)
            .copy_from_slice(&[1.5, 0.25, 0.3, 1.03, 0.245, 0.2]);
        z[6] = 0.8;
        let u = Vector2::new(0.8, 0.3);
        let dt = 1.0 / 30.0;
        let b = predict_leader(&model, LeaderMotion::HoldsFormation, &z, &u, dt, None).unwrap();
        assert_eq!((b[3], b[4]), (z[3], z[4]));
        assert!((b[5] - z[5]).abs() > 1e-4, "beta12 still moves: {b:?}");
        let w = formation_holding_velocity(&z.fixed_rows::<6>(0).into_owned(), &u, 0.5);
        assert_eq!((b[6], b[7]), (w[0], w[1]));
        let c = predict_leader(&model, LeaderMotion::HoldsBearing, &z, &u, dt, None).unwrap();
        assert_eq!(c[4], z[4]);
        assert!(
            (c[3] - z[3]).abs() > 1e-4,
            "l12 moves with A's speed: {c:?}"
        );
        // The velocity held over the step alone moves them (what B did before).
        let x = model
            .f(&z.fixed_rows::<6>(0).into_owned(), &u, &w, dt)
            .unwrap();
        assert!((x[3] - z[3]).abs() > 1e-6, "{x:?}");
        // Told the controller, B moves the formation as the controller commands, unchanged.
        let goal = ControllerConfig {
            l12_desired: 1.0,
            alpha12_desired: 0.25,
            k_l: 1.0,
            k_alpha: 1.0,
            max_v: None,
            max_w: None,
        };
        let told =
            predict_leader(&model, LeaderMotion::HoldsFormation, &z, &u, dt, Some(goal)).unwrap();
        assert!(told[3] < z[3], "{told:?}");
    }

    #[test]
    fn controlled_velocity_moves_the_formation_as_the_controller_commands() {
        // Regression for measurement 10 (`docs/dukf-reproduction.md`): model B's velocity
        // must make l12' = k_l (l12_d - l12), alpha12' = k_alpha (alpha12_d - alpha12), not 0.
        let model = PolarModel::new(0.5).unwrap();
        let x = PolarState::from_row_slice(&[1.5, 0.25, 0.3, 1.2, 0.3, -0.2]);
        let u = Vector2::new(0.7, 0.15);
        let goal = ControllerConfig {
            l12_desired: 1.0,
            alpha12_desired: 0.25,
            k_l: 0.8,
            k_alpha: 1.5,
            max_v: None,
            max_w: None,
        };
        let w = controlled_formation_velocity(&x, &u, 0.5, Some(goal));
        let dx = model.derivative(&x, &u, &w).unwrap();
        assert!((dx[3] - 0.8 * (1.0 - 1.2)).abs() < 1e-12, "{dx:?}");
        assert!((dx[4] - 1.5 * (0.25 - 0.3)).abs() < 1e-12, "{dx:?}");
        assert_eq!(
            controlled_formation_velocity(&x, &u, 0.5, None),
            formation_holding_velocity(&x, &u, 0.5)
        );
    }

    #[test]
    fn a_separation_crossing_zero_is_recovered_not_failed() {
        let model = PolarModel::new(0.5).unwrap();
        let mut z = LeaderState::zeros();
        z[3] = 0.02;
        z[6] = -50.0; // a leader speed far out: the step would cross l12 = 0
        let next = predict_leader(
            &model,
            LeaderMotion::Accelerates,
            &z,
            &Vector2::zeros(),
            0.1,
            None,
        )
        .unwrap();
        assert!(
            next[3] > 0.0 && next.iter().all(|v| v.is_finite()),
            "{next:?}"
        );
        z[3] = -1.0; // clamped to the smallest separation before the step
        let next = predict_leader(
            &model,
            LeaderMotion::HoldsBearing,
            &z,
            &Vector2::zeros(),
            0.1,
            None,
        )
        .unwrap();
        assert!(next[3] >= MIN_PREDICTED_SEPARATION * 0.5, "{next:?}");
    }

    #[test]
    fn the_noises_add_the_held_walk_and_the_controlled_formation_where_they_apply() {
        let t = LeaderMotionTuning::reference();
        let dt = 0.1;
        let [[qa, qb, qc], [ca, cb, cc]] = t.process_noises(&Vector3::new(1.0, 2.0, 3.0), dt);
        assert_eq!((qa[(0, 0)], qa[(2, 2)]), (1.0, 3.0));
        assert_eq!(qa[(9, 9)], (t.jerk[1] * dt).powi(2));
        let held = (t.held_rate_std[0] * dt).powi(2);
        assert_eq!(qb[(3, 3)], qa[(3, 3)] + held);
        assert_eq!((qc[(3, 3)], qc[(4, 4)] > qa[(4, 4)]), (qa[(3, 3)], true));
        assert_eq!((ca, cc), (qa, qa));
        assert_eq!(cb[(3, 3)], t.controlled_formation_q[0]);
        let mut bad = t.clone();
        bad.held_rate_std[1] = f64::NAN;
        assert!(bad.validate().is_err());
        bad = t;
        bad.mu0_a = -0.1;
        assert!(bad.validate().is_err());
    }

    /// #30: the manoeuvre hypothesis J takes C's place, predicts as A and adds its velocity
    /// jumps to A's noise; bad settings are refused.
    #[test]
    fn a_jump_hypothesis_replaces_c_with_a_velocity_noise() {
        let mut t = LeaderMotionTuning::reference();
        assert_eq!(t.motions(), LeaderMotion::ALL);
        t.jump = Some(LeaderJump {
            velocity_std: Vector2::new(0.05, 0.1),
            sojourn: 0.2,
            onset: 10.0,
        });
        assert!(t.validate().is_ok());
        assert_eq!(t.motions()[2], LeaderMotion::Jumps);
        let [[qa, _, qj], [_, _, cc]] = t.process_noises(&Vector3::new(1.0, 2.0, 3.0), 0.1);
        assert_eq!(qj[(6, 6)], qa[(6, 6)] + 0.05f64.powi(2));
        assert_eq!(qj[(7, 7)], qa[(7, 7)] + 0.1f64.powi(2));
        assert_eq!(qj[(4, 4)], qa[(4, 4)], "no held random walk in J");
        assert_eq!(cc, qa, "C's slot is unused with the controller known");
        let model = PolarModel::new(0.5).unwrap();
        let mut z = LeaderState::zeros();
        z.fixed_rows_mut::<6>(0)
            .copy_from(&PolarState::from_row_slice(&[
                1.5, 0.25, 0.3, 1.2, 0.3, -0.2,
            ]));
        z[6] = 0.8;
        z[7] = 0.2;
        z[8] = 0.1;
        let u = Vector2::new(0.7, 0.15);
        let a = predict_leader(&model, LeaderMotion::Accelerates, &z, &u, 0.1, None).unwrap();
        let j = predict_leader(&model, LeaderMotion::Jumps, &z, &u, 0.1, None).unwrap();
        assert_eq!(a, j);
        for (field, value) in [(0, -0.1), (2, 0.0), (3, f64::NAN)] {
            let mut bad = t.clone();
            let jump = bad.jump.as_mut().unwrap();
            match field {
                0 => jump.velocity_std[0] = value,
                2 => jump.sojourn = value,
                _ => jump.onset = value,
            }
            assert!(bad.validate().is_err(), "{field} = {value}");
        }
    }
}
