//! The leader's motion as a follower can hypothesise it from its own inputs: the
//! leader velocities that hold the formation, that hold the bearing, or that let the
//! follower's separation-bearing controller achieve what it commands (spec 2.4); and one
//! prediction step of the joint state `z = [x1, y1, theta1, l12, alpha12, beta12, v1, w1,
//! a_v, a_w]` under each of three motion hypotheses ([`LeaderMotion`]), which a
//! multiple-model filter mixes.

use nalgebra::{SVector, Vector2};

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
        LeaderMotion::Accelerates => Vector2::new(z[6], z[7]),
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
    match motion {
        LeaderMotion::Accelerates => {
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
}
