//! The follower changes its own set-point (issue #30, `far.yaml`'s step at 5 s).
//!
//! While the follower holds the formation, the IMM's model B (the formation held) takes
//! nearly all of the probability. When the follower then brakes to open the separation, B
//! says the leader braked with it, and the first measurement of the change lies far outside
//! the mixture's gate although model C predicts it. The follower knows its own plan:
//! told that its set-point changed (`FormationFilter::follower_setpoint_changed`), the
//! filter hands B's probability to C and takes that measurement.

#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use formation_filter::{FilterConfig, FilterDesign, FormationFilter};
use nalgebra::{Matrix3, Vector2, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use unicycle::{ControllerConfig, Formation, Inputs, PolarModel, PolarState};

const DT: f64 = 1.0 / 30.0;
const D: f64 = 0.5;
/// The measurement noise: 1.4 mm, 1.1 mrad, 0.05 mrad (the `far` demo's vision at 3.3 m).
const MEASUREMENT_STD: [f64; 3] = [1.4e-3, 1.1e-3, 5e-5];
/// The 99.9 % point of a chi-square with 3 degrees of freedom: the tracker's gate.
const GATE: f64 = 16.27;
/// Frames in formation before the follower brakes.
const HOLD: usize = 90;

/// Drives the leader straight at 0.5 m/s and the follower behind it at the same speed for
/// `HOLD` frames, then brakes the follower to 0.1 m/s; `notify` tells the filter when it
/// brakes, `controller` whether it knows the follower's controller. Returns the first
/// braking frame's NIS against the filter's prediction, the model probabilities before and
/// after the notice, and the largest change of `l12` while holding.
fn run(seed: u64, notify: bool, controller: bool) -> (f64, [f64; 3], [f64; 3], f64) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let model = PolarModel::new(D).unwrap();
    let mut x = PolarState::from_row_slice(&[1.5, 0.25, 0.0, 1.047, 0.233, 0.233]);
    let mut config = FilterConfig::new(D, DT, x);
    config.tuning.design = FilterDesign::Imm;
    config.tuning.w0 = Vector2::new(0.5, 0.0);
    let r = Matrix3::from_diagonal(&Vector3::from(MEASUREMENT_STD.map(|s| s * s)));
    let y0 = PolarModel::h(&x);
    let started = config.started_at(&y0, &r, 0.1).unwrap();
    let mut filter = FormationFilter::new(&started).unwrap();
    if controller {
        filter
            .set_follower_controller(Some(ControllerConfig::hold(&Formation::from_vector(&y0))))
            .unwrap();
    }
    let leader = Vector2::new(0.5, 0.0);
    let mut held = 0.0f64;
    let mut probabilities = [[0.0; 3]; 2];
    for k in 1..=HOLD + 1 {
        let follower = if k <= HOLD {
            Vector2::new(0.5, 0.0)
        } else {
            Vector2::new(0.1, 0.0)
        };
        if k == HOLD + 1 {
            probabilities[0] = filter.model_probabilities().unwrap();
            if notify {
                filter.follower_setpoint_changed().unwrap();
            }
            probabilities[1] = filter.model_probabilities().unwrap();
        }
        x = model.f(&x, &follower, &leader, DT).unwrap();
        let truth = PolarModel::h(&x);
        let y = truth + Vector3::from_fn(|i, _| MEASUREMENT_STD[i] * unit.sample(&mut rng));
        let u = Inputs::new(follower[0], follower[1]);
        if k == HOLD + 1 {
            let nis = filter.predicted(u).unwrap().nis(&y, &r).unwrap();
            return (nis, probabilities[0], probabilities[1], held);
        }
        held = held.max((truth[0] - y0[0]).abs());
        filter.step(&y, &r, u).unwrap();
    }
    unreachable!()
}

#[test]
fn told_of_its_set_point_change_the_filter_expects_the_separation_to_open() {
    let mut inside = 0;
    for seed in 1..=8 {
        let (plain, before, same, held) = run(seed, false, false);
        // The scene is what it says: the formation held, then a step of 13 mm in one frame.
        assert!(held < 1e-9, "l12 moved {held} m while held");
        assert!(before[1] > 0.9, "B holds {before:?} before the brake");
        assert_eq!(before, same);
        // Without the notice: 139-255 on these seeds.
        assert!(
            plain > 5.0 * GATE,
            "seed {seed}: NIS {plain} without the notice"
        );
        let (told, _, after, _) = run(seed, true, false);
        assert_eq!(after[1], 0.0);
        assert!(
            (after[2] - (before[1] + before[2])).abs() < 1e-12,
            "{after:?}"
        );
        // With it: 2.9-20.8, a chi-square's spread over a prediction C had to take from B.
        assert!(
            told < plain / 5.0,
            "seed {seed}: NIS {told} told, {plain} not"
        );
        inside += usize::from(told < GATE);
    }
    assert!(
        inside >= 6,
        "{inside} of 8 first braking frames inside the gate"
    );
}

#[test]
fn with_the_controller_known_the_notice_changes_nothing() {
    let (_, before, after, _) = run(1, true, true);
    assert_eq!(before, after);
}
