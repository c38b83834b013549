//! Invariants of the unicycle and polar models (spec 2.2-2.4).

use std::f64::consts::PI;

use nalgebra::Vector2;
use proptest::prelude::*;
use unicycle::{
    ControllerConfig, Formation, Inputs, MIN_SEPARATION, PlanarPose, PolarModel, PolarState,
    SeparationBearingController, UnicycleError, wrap_angle,
};

const DT: f64 = 1.0 / 30.0;

fn angle_diff(a: f64, b: f64) -> f64 {
    wrap_angle(a - b).abs()
}

fn pose() -> impl Strategy<Value = PlanarPose> {
    (-5.0..5.0f64, -5.0..5.0f64, -PI..PI).prop_map(|(x, y, t)| PlanarPose::new(x, y, t))
}

fn inputs() -> impl Strategy<Value = Inputs> {
    (-1.0..1.0f64, -1.0..1.0f64).prop_map(|(v, w)| Inputs::new(v, w))
}

/// A follower and a leader 1.5-4 m from its camera, in any relative configuration.
fn configuration() -> impl Strategy<Value = (PlanarPose, PlanarPose, f64)> {
    (pose(), 1.5..4.0f64, -PI..PI, -PI..PI, 0.0..0.6f64).prop_map(
        |(follower, l, bearing, heading, d)| {
            let (xc, yc) = follower.point_ahead(d);
            let zeta = follower.theta + bearing;
            let leader = PlanarPose::new(xc + l * zeta.cos(), yc + l * zeta.sin(), heading);
            (leader, follower, d)
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Spec 2.4: integrating the polar equations agrees with integrating both unicycles in
    /// Cartesian form and applying 2.3, over 1 s at dt = 1/30 (inputs change every step).
    #[test]
    fn polar_model_agrees_with_cartesian_unicycles(
        (leader0, follower0, d) in configuration(),
        u1 in prop::collection::vec(inputs(), 30),
        u2 in prop::collection::vec(inputs(), 30),
    ) {
        let model = PolarModel::new(d).unwrap();
        let mut x = model.state_from_poses(&leader0, &follower0).unwrap();
        let (mut leader, mut follower) = (leader0, follower0);
        for k in 0..30 {
            let cart_leader = leader.integrate_rk4(u1[k], DT).unwrap();
            let exact_leader = leader.integrate_exact(u1[k], DT).unwrap();
            // The two unicycle integrators agree to RK4 accuracy.
            prop_assert!((cart_leader.x - exact_leader.x).abs() < 1e-8);
            prop_assert!(angle_diff(cart_leader.theta, exact_leader.theta) < 1e-12);
            leader = exact_leader;
            follower = follower.integrate_exact(u2[k], DT).unwrap();
            x = model.f(&x, &u2[k].into(), &u1[k].into(), DT).unwrap();
        }
        let truth = Formation::from_poses(&leader, &follower, d).unwrap();
        prop_assert!((x[0] - leader.x).abs() < 1e-6, "x1 {} vs {}", x[0], leader.x);
        prop_assert!((x[1] - leader.y).abs() < 1e-6, "y1 {} vs {}", x[1], leader.y);
        prop_assert!(angle_diff(x[2], leader.theta) < 1e-9);
        prop_assert!((x[3] - truth.l12).abs() < 1e-6, "l12 {} vs {}", x[3], truth.l12);
        prop_assert!(angle_diff(x[4], truth.alpha12) < 1e-6, "alpha {} vs {}", x[4], truth.alpha12);
        prop_assert!(angle_diff(x[5], truth.beta12) < 1e-6, "beta {} vs {}", x[5], truth.beta12);
        // The follower pose implied by the polar state is the Cartesian one.
        let f = model.follower_pose(&x).unwrap();
        prop_assert!((f.x - follower.x).abs() < 1e-5 && (f.y - follower.y).abs() < 1e-5);
    }

    /// Every step returns angles in (-pi, pi], even from unwrapped inputs and fast turning.
    #[test]
    fn angles_stay_wrapped(
        (leader, follower, d) in configuration(),
        extra in prop::array::uniform3(-20.0..20.0f64),
        w1 in -6.0..6.0f64,
        w2 in -6.0..6.0f64,
    ) {
        let model = PolarModel::new(d).unwrap();
        let mut x = model.state_from_poses(&leader, &follower).unwrap();
        x[2] += extra[0];
        x[4] += extra[1];
        x[5] += extra[2];
        for _ in 0..10 {
            x = model.f(&x, &Vector2::new(0.3, w2), &Vector2::new(0.3, w1), DT).unwrap();
            for i in unicycle::STATE_ANGLES {
                prop_assert!(x[i] > -PI && x[i] <= PI, "component {i} = {}", x[i]);
            }
        }
        let p = follower.integrate_exact(Inputs::new(0.5, w2 * 10.0), 1.0).unwrap();
        prop_assert!(p.theta > -PI && p.theta <= PI);
    }

    /// Formation variables -> leader pose -> formation variables is the identity, and so is
    /// poses -> formation -> follower pose.
    #[test]
    fn formation_round_trips((leader, follower, d) in configuration()) {
        let f = Formation::from_poses(&leader, &follower, d).unwrap();
        let l = f.leader_pose(&follower, d).unwrap();
        prop_assert!((l.x - leader.x).abs() < 1e-9 && (l.y - leader.y).abs() < 1e-9);
        prop_assert!(angle_diff(l.theta, leader.theta) < 1e-9);
        let back = Formation::from_poses(&l, &follower, d).unwrap();
        prop_assert!((back.l12 - f.l12).abs() < 1e-9);
        prop_assert!(angle_diff(back.alpha12, f.alpha12) < 1e-9);
        prop_assert!(angle_diff(back.beta12, f.beta12) < 1e-9);
        let fo = f.follower_pose(&leader, d).unwrap();
        prop_assert!((fo.x - follower.x).abs() < 1e-9 && (fo.y - follower.y).abs() < 1e-9);
        prop_assert!(angle_diff(fo.theta, follower.theta) < 1e-9);
    }

    /// l12 at or below the minimum gives the typed error from every entry point.
    #[test]
    fn small_separation_is_an_error(
        l in -2.0..MIN_SEPARATION,
        (leader, follower, d) in configuration(),
        u in inputs(),
    ) {
        let model = PolarModel::new(d).unwrap();
        let mut x = model.state_from_poses(&leader, &follower).unwrap();
        x[3] = l;
        let is_sep = |e: UnicycleError| matches!(e, UnicycleError::SeparationTooSmall { .. });
        prop_assert!(is_sep(model.f(&x, &u.into(), &u.into(), DT).unwrap_err()));
        prop_assert!(is_sep(model.derivative(&x, &u.into(), &u.into()).unwrap_err()));
        prop_assert!(is_sep(model.follower_pose(&x).unwrap_err()));
        let f = Formation { l12: l, alpha12: 0.1, beta12: 0.2 };
        prop_assert!(is_sep(f.leader_pose(&follower, d).unwrap_err()));
        let ctrl = SeparationBearingController::new(0.5, ControllerConfig {
            l12_desired: 1.0, alpha12_desired: 0.0, k_l: 1.0, k_alpha: 1.0,
            max_v: None, max_w: None,
        }).unwrap();
        prop_assert!(is_sep(ctrl.inputs(&f, u).unwrap_err()));
    }

    /// Any non-finite component of state or inputs gives the typed error, never NaN.
    #[test]
    fn non_finite_input_is_an_error(
        (leader, follower, d) in configuration(),
        which in 0usize..10,
        bad in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)],
    ) {
        let model = PolarModel::new(d).unwrap();
        let mut x = model.state_from_poses(&leader, &follower).unwrap();
        let mut u = Vector2::new(0.2, 0.1);
        let mut w = Vector2::new(0.5, -0.1);
        match which {
            0..=5 => x[which] = bad,
            6..=7 => u[which - 6] = bad,
            _ => w[which - 8] = bad,
        }
        let err = model.f(&x, &u, &w, DT).unwrap_err();
        prop_assert!(matches!(err, UnicycleError::NonFinite { .. }), "{err:?}");
        let err = model.derivative(&x, &u, &w).unwrap_err();
        prop_assert!(matches!(err, UnicycleError::NonFinite { .. }), "{err:?}");
        let mut p = follower;
        p.x = bad;
        let err = p.integrate_exact(Inputs::new(0.1, 0.1), DT).unwrap_err();
        prop_assert!(matches!(err, UnicycleError::NonFinite { .. }), "{:?}", err);
        let err = Formation::from_poses(&leader, &p, d).unwrap_err();
        prop_assert!(matches!(err, UnicycleError::NonFinite { .. }), "{:?}", err);
    }

    /// The exact integration of a unicycle is an arc: constant speed along it, and the
    /// straight-line limit for tiny w is continuous with the arc.
    #[test]
    fn exact_integration_matches_fine_rk4(p in pose(), u in inputs(), dt in 0.01..2.0f64) {
        let exact = p.integrate_exact(u, dt).unwrap();
        let mut q = p;
        let n = 200;
        for _ in 0..n {
            q = q.integrate_rk4(u, dt / n as f64).unwrap();
        }
        prop_assert!((exact.x - q.x).abs() < 1e-9 && (exact.y - q.y).abs() < 1e-9);
        let tiny = p.integrate_exact(Inputs::new(u.v, 1e-12), dt).unwrap();
        let straight = p.integrate_exact(Inputs::new(u.v, 0.0), dt).unwrap();
        prop_assert!((tiny.x - straight.x).abs() < 1e-11 && (tiny.y - straight.y).abs() < 1e-11);
    }
}

#[test]
fn bad_dt_and_offset_are_errors() {
    let model = PolarModel::new(0.5).unwrap();
    let x = PolarState::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0);
    let z = Vector2::zeros();
    for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            model.f(&x, &z, &z, dt),
            Err(UnicycleError::InvalidTimeStep { .. })
        ));
        assert!(matches!(
            PlanarPose::default().integrate_exact(Inputs::default(), dt),
            Err(UnicycleError::InvalidTimeStep { .. })
        ));
    }
    for d in [-0.1, f64::NAN] {
        assert!(matches!(
            PolarModel::new(d),
            Err(UnicycleError::InvalidOffset { .. })
        ));
    }
    let cfg = ControllerConfig::hold(&Formation {
        l12: 1.0,
        alpha12: 0.0,
        beta12: 0.0,
    });
    assert!(matches!(
        SeparationBearingController::new(0.0, cfg),
        Err(UnicycleError::ControllerNeedsOffset { .. })
    ));
    let bad_gain = ControllerConfig { k_l: -1.0, ..cfg };
    assert!(matches!(
        SeparationBearingController::new(0.5, bad_gain),
        Err(UnicycleError::InvalidControllerSetting { name: "k_l", .. })
    ));
}

/// A step that would cross l12 = 0 inside the RK4 stages is refused rather than returning
/// garbage: the leader 5 cm ahead, driving straight at the camera.
#[test]
fn step_through_the_singularity_is_an_error() {
    let model = PolarModel::new(0.5).unwrap();
    let follower = PlanarPose::new(0.0, 0.0, 0.0);
    let leader = PlanarPose::new(0.55, 0.0, PI);
    let x = model.state_from_poses(&leader, &follower).unwrap();
    let err = model
        .f(&x, &Vector2::zeros(), &Vector2::new(3.0, 0.0), DT)
        .unwrap_err();
    assert!(matches!(err, UnicycleError::SeparationTooSmall { .. }));
}

/// The controller's closed loop is the designed linear one: l12 and alpha12 errors decay as
/// exp(-k t) (checked at t = 1 s against the polar model with the controller in the loop).
#[test]
fn controller_linearises_the_outputs() {
    let d = 0.5;
    let model = PolarModel::new(d).unwrap();
    let follower = PlanarPose::new(0.0, 0.0, 0.0);
    let leader = PlanarPose::new(1.5, 0.25, 0.0);
    let mut x = model.state_from_poses(&leader, &follower).unwrap();
    let cfg = ControllerConfig {
        l12_desired: x[3] + 0.3,
        alpha12_desired: x[4] - 0.2,
        k_l: 1.0,
        k_alpha: 2.0,
        max_v: None,
        max_w: None,
    };
    let ctrl = SeparationBearingController::new(d, cfg).unwrap();
    let (e_l0, e_a0) = (cfg.l12_desired - x[3], cfg.alpha12_desired - x[4]);
    // Controller evaluated every 1/300 s (zero-order hold): close to continuous time.
    let h = 1.0 / 300.0;
    for k in 0..300 {
        let t = k as f64 * h;
        let w = Vector2::new(0.8 + 0.2 * (0.5 * t).sin(), 0.2 * (0.4 * t).sin());
        let f = Formation::from_vector(&PolarModel::h(&x));
        let u = ctrl.inputs(&f, w.into()).unwrap();
        x = model.f(&x, &u.into(), &w, h).unwrap();
    }
    let e_l = cfg.l12_desired - x[3];
    let e_a = wrap_angle(cfg.alpha12_desired - x[4]);
    assert!((e_l - e_l0 * (-1.0f64).exp()).abs() < 2e-3, "{e_l}");
    assert!((e_a - e_a0 * (-2.0f64).exp()).abs() < 2e-3, "{e_a}");
}

#[test]
fn saturation_limits_the_inputs() {
    let f = Formation {
        l12: 3.0,
        alpha12: 0.5,
        beta12: -0.4,
    };
    let cfg = ControllerConfig {
        l12_desired: 1.0,
        alpha12_desired: 0.0,
        k_l: 5.0,
        k_alpha: 5.0,
        max_v: Some(0.3),
        max_w: Some(0.2),
    };
    let free = SeparationBearingController::new(
        0.5,
        ControllerConfig {
            max_v: None,
            max_w: None,
            ..cfg
        },
    )
    .unwrap()
    .inputs(&f, Inputs::new(1.0, 0.3))
    .unwrap();
    assert!(free.v.abs() > 0.3 && free.w.abs() > 0.2, "{free:?}");
    let sat = SeparationBearingController::new(0.5, cfg)
        .unwrap()
        .inputs(&f, Inputs::new(1.0, 0.3))
        .unwrap();
    assert_eq!(sat.v, 0.3 * free.v.signum());
    assert_eq!(sat.w, 0.2 * free.w.signum());
}
