//! Exponential and logarithm maps, their Jacobian, and the pose type.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use pose::Pose;
use pose::so3::{exp, exp_point_jacobian, left_jacobian, log};
use proptest::prelude::*;
use std::f64::consts::PI;

fn axis() -> impl Strategy<Value = Vector3<f64>> {
    prop::array::uniform3(-1.0f64..1.0)
        .prop_filter("non-zero axis", |a| Vector3::from(*a).norm() > 1e-3)
        .prop_map(|a| Vector3::from(a).normalize())
}

/// Angles spread over the whole range, with the two delicate ends over-represented.
fn angle() -> impl Strategy<Value = f64> {
    prop_oneof![
        0.0..PI - 1e-9,
        0.0..1e-3,
        (1e-9f64..1e-3).prop_map(|d| PI - d),
        Just(0.0)
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn log_inverts_exp(a in axis(), t in angle()) {
        let w = a * t;
        let back = log(&exp(&w));
        // Near pi the axis is read from the symmetric part, which is accurate to ~1e-8 when
        // pi - t ~ 1e-9 (the rotation matrix itself only holds ~1e-16 of information there).
        let tol = if t > PI - 1e-3 { 1e-7 } else { 1e-12 };
        prop_assert!((back - w).norm() <= tol * (1.0 + t), "w {w:?} back {back:?}");
    }

    #[test]
    fn exp_is_a_rotation(a in axis(), t in 0.0f64..10.0) {
        let r = exp(&(a * t));
        prop_assert!((r.transpose() * r - Matrix3::identity()).amax() < 1e-14);
        prop_assert!((r.determinant() - 1.0).abs() < 1e-14);
        // The axis is fixed and the angle is t.
        prop_assert!((r * a - a).norm() < 1e-14);
    }

    #[test]
    fn exp_point_jacobian_matches_finite_differences(a in axis(), t in angle(), p in prop::array::uniform3(-2.0f64..2.0)) {
        let w = a * t.min(3.0);
        let p = Vector3::from(p);
        let j = exp_point_jacobian(&w, &p);
        let h = 1e-6;
        for c in 0..3 {
            let mut d = Vector3::zeros();
            d[c] = h;
            let fd = (exp(&(w + d)) * p - exp(&(w - d)) * p) / (2.0 * h);
            prop_assert!((fd - j.column(c)).norm() < 1e-8 * (1.0 + p.norm()), "column {c}: fd {fd:?} analytic {:?}", j.column(c));
        }
    }

    #[test]
    fn left_jacobian_linearises_exp(a in axis(), t in 0.0f64..3.0, d in prop::array::uniform3(-1e-6f64..1e-6)) {
        let w = a * t;
        let d = Vector3::from(d);
        let lhs = exp(&(w + d));
        let rhs = exp(&(left_jacobian(&w) * d)) * exp(&w);
        prop_assert!((lhs - rhs).amax() < 1e-11);
    }

    #[test]
    fn pose_isometry_round_trip(a in axis(), t in 0.0f64..3.1, tr in prop::array::uniform3(-5.0f64..5.0), p in prop::array::uniform3(-1.0f64..1.0)) {
        let pose = Pose::new(a * t, Vector3::from(tr));
        let iso: Isometry3<f64> = pose.into();
        let p = Point3::from(Vector3::from(p));
        prop_assert!((iso * p - pose.transform_point(&p)).norm() < 1e-12);
        let back = Pose::from(iso);
        prop_assert!(back.rotation_angle_to(&pose) < 1e-12);
        prop_assert!((back.translation - pose.translation).norm() < 1e-12);
        let q = pose.inverse().transform_point(&pose.transform_point(&p));
        prop_assert!((q - p).norm() < 1e-12);
    }
}

#[test]
fn exp_of_zero_is_identity_and_log_of_identity_is_zero() {
    assert_eq!(exp(&Vector3::zeros()), Matrix3::identity());
    assert_eq!(log(&Matrix3::identity()), Vector3::zeros());
}

#[test]
fn log_at_exactly_pi() {
    let w = Vector3::new(0.0, 0.6, 0.8) * PI;
    let back = log(&exp(&w));
    // Both signs are the same rotation at pi.
    assert!((back.norm() - PI).abs() < 1e-12);
    assert!((exp(&back) - exp(&w)).amax() < 1e-12);
}

#[test]
fn tiny_angles_keep_full_precision() {
    let w = Vector3::new(3e-12, -1e-12, 2e-12);
    assert!((log(&exp(&w)) - w).norm() < 1e-24);
}

#[test]
fn normalized_wraps_angle_above_pi() {
    let a = Vector3::new(0.0, 0.0, 1.0);
    let p = Pose::new(a * (PI + 0.5), Vector3::zeros()).normalized();
    assert!((p.rotation - a * (0.5 - PI)).norm() < 1e-12);
}
