//! Lens distortion: plumb bob, rational polynomial and fisheye (equidistant).

use nalgebra::Point2;
use pose::{Distortion, DistortionModel, Intrinsics, PoseError};
use proptest::prelude::*;

/// A 1280x720 camera with square pixels and the given horizontal field of view.
fn camera(hfov_deg: f64) -> Intrinsics {
    Intrinsics::from_hfov(hfov_deg.to_radians(), 1280, 720).expect("valid field of view")
}

/// Asserts `undistort(distort(p)) == p` within 1e-9 px for an ideal pixel `p`.
fn round_trip_ideal(d: &Distortion, k: &Intrinsics, p: Point2<f64>) -> Result<(), TestCaseError> {
    let q = d.distort_pixel(k, &p);
    let back = d
        .undistort_pixel(k, &q)
        .map_err(|e| TestCaseError::fail(format!("{d:?} {p:?}: {e}")))?;
    prop_assert!(
        (back - p).norm() < 1e-9,
        "{d:?}: {p:?} -> {q:?} -> {back:?}"
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn plumb_bob_undistort_inverts_distort_over_the_image(
        k1 in -0.25f64..0.25, k2 in -0.05f64..0.05, p1 in -0.002f64..0.002, p2 in -0.002f64..0.002,
        k3 in -0.01f64..0.01, hfov in 40f64..65.0, u in -0.5f64..1279.5, v in -0.5f64..719.5,
    ) {
        let d = Distortion::plumb_bob(k1, k2, p1, p2, k3).unwrap();
        round_trip_ideal(&d, &camera(hfov), Point2::new(u, v))?;
    }

    #[test]
    fn rational_undistort_inverts_distort_over_the_image(
        k1 in -0.1f64..0.3, k2 in -0.05f64..0.05, p1 in -0.002f64..0.002, p2 in -0.002f64..0.002,
        k3 in -0.01f64..0.01, k4 in 0.0f64..0.4, k5 in -0.02f64..0.02, k6 in -0.005f64..0.005,
        hfov in 40f64..75.0, u in -0.5f64..1279.5, v in -0.5f64..719.5,
    ) {
        let d = Distortion::rational_polynomial([k1, k2, p1, p2, k3, k4, k5, k6]).unwrap();
        round_trip_ideal(&d, &camera(hfov), Point2::new(u, v))?;
    }

    #[test]
    fn equidistant_undistort_inverts_distort_over_the_image(
        k1 in -0.05f64..0.05, k2 in -0.02f64..0.02, k3 in -0.005f64..0.005, k4 in -0.001f64..0.001,
        hfov in 40f64..150.0, u in -0.5f64..1279.5, v in -0.5f64..719.5,
    ) {
        let d = Distortion::equidistant(k1, k2, k3, k4).unwrap();
        round_trip_ideal(&d, &camera(hfov), Point2::new(u, v))?;
    }

    /// The other direction, from a detected (distorted) pixel anywhere in a fisheye image: a
    /// pixel whose ray lies within 90 degrees of the axis on the rising part of the lens
    /// profile undistorts and distorts back to itself; any other is a typed error.
    #[test]
    fn equidistant_pixels_round_trip_or_are_refused(
        k1 in -0.05f64..0.05, k2 in -0.02f64..0.02, k3 in -0.005f64..0.005, k4 in -0.001f64..0.001,
        f in 380f64..700.0, u in -0.5f64..1279.5, v in -0.5f64..799.5,
    ) {
        let k = Intrinsics::square_pixels(f, f, 639.5, 399.5).unwrap();
        let d = Distortion::equidistant(k1, k2, k3, k4).unwrap();
        let q = Point2::new(u, v);
        let n = k.pixel_to_normalized(&q);
        let rd = n.x.hypot(n.y);
        // The ray's angle by a fine march up the profile while it rises; None past a fold.
        let theta_d = |t: f64| {
            let t2 = t * t;
            t * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
        };
        let mut theta = None;
        let mut t = 0.0;
        while t < std::f64::consts::PI && theta_d(t + 1e-4) > theta_d(t) {
            if theta_d(t) >= rd {
                theta = Some(t);
                break;
            }
            t += 1e-4;
        }
        match (theta, d.undistort_pixel(&k, &q)) {
            (Some(t), Ok(p)) if t < std::f64::consts::FRAC_PI_2 - 1e-3 => {
                let back = d.distort_pixel(&k, &p);
                prop_assert!((back - q).norm() < 1e-9, "{q:?} -> {p:?} -> {back:?}");
            }
            (Some(t), Err(e)) if t < std::f64::consts::FRAC_PI_2 - 1e-3 => {
                return Err(TestCaseError::fail(format!("{q:?} at {t} rad: {e}")));
            }
            (Some(t), Err(PoseError::BeyondPinholeView { angle, .. })) if t > std::f64::consts::FRAC_PI_2 + 1e-3 => {
                prop_assert!(angle >= std::f64::consts::FRAC_PI_2);
            }
            (Some(t), Ok(p)) if t > std::f64::consts::FRAC_PI_2 + 1e-3 => {
                return Err(TestCaseError::fail(format!("{q:?} at {t} rad gave {p:?}")));
            }
            (None, Ok(p)) => {
                return Err(TestCaseError::fail(format!("{q:?} beyond the fold gave {p:?}")));
            }
            (None, Err(e)) => {
                prop_assert!(matches!(e, PoseError::UndistortionNotConverged { .. } | PoseError::BeyondPinholeView { .. }), "{e}");
            }
            // Within 1e-3 rad of 90 degrees either answer is right.
            _ => {}
        }
    }

    #[test]
    fn pixel_round_trip(x in 0.0f64..640.0, y in 0.0f64..480.0) {
        let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480).unwrap();
        let d = Distortion::plumb_bob(-0.12, 0.035, 0.001, -0.0005, 0.0).unwrap();
        let m = Point2::new(x, y);
        let back = d.distort_pixel(&k, &d.undistort_pixel(&k, &m).unwrap());
        prop_assert!((back - m).norm() < 1e-9);
    }
}

#[test]
fn distort_matches_the_opencv_formula() {
    let d = Distortion::plumb_bob(0.1, 0.01, 0.002, 0.003, 0.001).unwrap();
    let (x, y) = (0.3, -0.2);
    let r2: f64 = x * x + y * y;
    let radial = 1.0 + 0.1 * r2 + 0.01 * r2 * r2 + 0.001 * r2 * r2 * r2;
    let xd = x * radial + 2.0 * 0.002 * x * y + 0.003 * (r2 + 2.0 * x * x);
    let yd = y * radial + 0.002 * (r2 + 2.0 * y * y) + 2.0 * 0.003 * x * y;
    let got = d.distort(&Point2::new(x, y));
    assert!((got.x - xd).abs() < 1e-15 && (got.y - yd).abs() < 1e-15);
}

/// OpenCV's `projectPoints` with 8 coefficients (the docs of `calib3d`, "rational model").
#[test]
fn rational_distort_matches_the_opencv_formula() {
    let c = [0.1, -0.02, 0.0006, -0.0004, 0.001, 0.35, 0.01, 0.001];
    let d = Distortion::rational_polynomial(c).unwrap();
    let [k1, k2, p1, p2, k3, k4, k5, k6] = c;
    let (x, y) = (0.45, -0.31);
    let r2: f64 = x * x + y * y;
    let (r4, r6) = (r2 * r2, r2 * r2 * r2);
    let radial = (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
    let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
    let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
    let got = d.distort(&Point2::new(x, y));
    assert!((got.x - xd).abs() < 1e-15 && (got.y - yd).abs() < 1e-15);
    // The same coefficients with the denominator zero are the plumb bob model.
    let rational = Distortion::rational_polynomial([k1, k2, p1, p2, k3, 0.0, 0.0, 0.0]).unwrap();
    let plumb = Distortion::plumb_bob(k1, k2, p1, p2, k3).unwrap();
    let n = Point2::new(x, y);
    assert!((rational.distort(&n) - plumb.distort(&n)).norm() < 1e-15);
}

/// OpenCV's `cv::fisheye::projectPoints` (the docs of the `fisheye` namespace).
#[test]
fn equidistant_distort_matches_the_opencv_formula() {
    let (k1, k2, k3, k4) = (0.05, -0.01, 0.002, -0.0003);
    let d = Distortion::equidistant(k1, k2, k3, k4).unwrap();
    for (a, b) in [(0.45, -0.31), (1.7, 0.9), (-0.02, 0.001)] {
        let r: f64 = f64::hypot(a, b);
        let theta = r.atan();
        let t2 = theta * theta;
        let theta_d = theta * (1.0 + k1 * t2 + k2 * t2 * t2 + k3 * t2.powi(3) + k4 * t2.powi(4));
        let (xd, yd) = (theta_d / r * a, theta_d / r * b);
        let got = d.distort(&Point2::new(a, b));
        assert!(
            (got.x - xd).abs() < 1e-15 && (got.y - yd).abs() < 1e-15,
            "{got:?}"
        );
    }
    // The optical axis maps to itself.
    assert_eq!(d.distort(&Point2::origin()), Point2::origin());
    // With zero coefficients it is the ideal f-theta lens, not the identity.
    let ftheta = Distortion::equidistant(0.0, 0.0, 0.0, 0.0).unwrap();
    assert!(!ftheta.is_identity());
    assert!((ftheta.distort(&Point2::new(1.0, 0.0)).x - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
}

#[test]
fn non_invertible_region_reports_non_convergence() {
    // Strong barrel distortion folds over at r ~ 0.58: radii beyond the fold's image have no
    // preimage.
    let d = Distortion::plumb_bob(-1.0, 0.0, 0.0, 0.0, 0.0).unwrap();
    let e = d.undistort(&Point2::new(0.9, 0.0)).unwrap_err();
    assert!(
        matches!(e, PoseError::UndistortionNotConverged { iterations, .. } if iterations == pose::UNDISTORT_MAX_ITERATIONS),
        "{e:?}"
    );
    // A fisheye profile theta (1 - theta^2 / 2) peaks at theta_d ~ 0.544.
    let d = Distortion::equidistant(-0.5, 0.0, 0.0, 0.0).unwrap();
    let e = d.undistort(&Point2::new(0.0, 0.8)).unwrap_err();
    assert!(
        matches!(e, PoseError::UndistortionNotConverged { .. }),
        "{e:?}"
    );
    // A ray beyond 90 degrees (an f-theta lens sees it at theta_d = 1.8 rad) has no pinhole
    // image.
    let d = Distortion::equidistant(0.0, 0.0, 0.0, 0.0).unwrap();
    let e = d.undistort(&Point2::new(1.8, 0.0)).unwrap_err();
    assert!(
        matches!(e, PoseError::BeyondPinholeView { angle, .. } if (angle - 1.8).abs() < 1e-9),
        "{e:?}"
    );
    assert!(e.to_string().contains("no pinhole image"), "{e}");
}

#[test]
fn bad_coefficients_are_rejected() {
    assert!(matches!(
        Distortion::plumb_bob(f64::NAN, 0.0, 0.0, 0.0, 0.0),
        Err(PoseError::InvalidDistortion { name: "k1", .. })
    ));
    assert!(matches!(
        Distortion::plumb_bob(0.0, 0.0, f64::INFINITY, 0.0, 0.0),
        Err(PoseError::InvalidDistortion { name: "p1", .. })
    ));
    assert!(matches!(
        Distortion::rational_polynomial([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::NAN, 0.0]),
        Err(PoseError::InvalidDistortion { name: "k5", .. })
    ));
    assert!(matches!(
        Distortion::equidistant(0.0, 0.0, 0.0, f64::NEG_INFINITY),
        Err(PoseError::InvalidDistortion { name: "k4", .. })
    ));
    // Built directly from a variant, a NaN coefficient is reported, not propagated.
    let raw = Distortion::Equidistant {
        k1: f64::NAN,
        k2: 0.0,
        k3: 0.0,
        k4: 0.0,
    };
    assert!(matches!(
        raw.undistort(&Point2::new(0.1, 0.0)),
        Err(PoseError::InvalidDistortion { name: "k1", .. })
    ));
    assert!(matches!(
        Distortion::default().undistort(&Point2::new(f64::NAN, 0.0)),
        Err(PoseError::NonFinite { .. })
    ));
}

#[test]
fn coefficient_vectors_by_model_and_by_opencv_length() {
    // Regression (#11): the count error read "coefficient count (need 4 or 5) is not
    // finite (3)"; then it named only plumb_bob. It lists what is accepted.
    let e = Distortion::from_opencv(&[0.1, 0.2, 0.0]).unwrap_err();
    assert!(
        matches!(e, PoseError::DistortionCount { count: 3, .. }),
        "{e}"
    );
    let msg = e.to_string();
    for says in [
        "4 or 5",
        "plumb_bob",
        "8 (rational_polynomial",
        "12 or 14",
        "equidistant",
        "got 3",
    ] {
        assert!(msg.contains(says), "{msg} lacks {says}");
    }
    let d = Distortion::from_opencv(&[0.1, 0.2, 0.01, 0.02]).unwrap();
    assert_eq!(d, Distortion::plumb_bob(0.1, 0.2, 0.01, 0.02, 0.0).unwrap());
    let eight = [0.1, -0.02, 0.0006, -0.0004, 0.001, 0.35, 0.01, 0.001];
    let d = Distortion::from_opencv(&eight).unwrap();
    assert_eq!(d.model(), DistortionModel::RationalPolynomial);
    assert_eq!(d.coefficients(), eight.to_vec());
    // 12 and 14 values with the thin-prism and tilt terms zero are the rational model...
    let mut fourteen = eight.to_vec();
    fourteen.extend([0.0; 6]);
    assert_eq!(Distortion::from_opencv(&fourteen).unwrap(), d);
    assert_eq!(Distortion::from_opencv(&fourteen[..12]).unwrap(), d);
    // ...and refused when they are not.
    fourteen[9] = 0.001;
    let e = Distortion::from_opencv(&fourteen).unwrap_err();
    assert!(
        matches!(e, PoseError::UnsupportedDistortion { index: 9, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("thin-prism"), "{e}");

    // By model name, as ROS CameraInfo carries them.
    let fish = Distortion::from_name("equidistant", &[0.05, -0.01, 0.002, -0.0003]).unwrap();
    assert_eq!(
        fish,
        Distortion::equidistant(0.05, -0.01, 0.002, -0.0003).unwrap()
    );
    assert_eq!(
        Distortion::from_name("fisheye", &fish.coefficients()).unwrap(),
        fish
    );
    assert_eq!(
        Distortion::from_name("plumb_bob", &[]).unwrap(),
        Distortion::NONE
    );
    assert_eq!(
        Distortion::from_name("rational_polynomial", &[]).unwrap(),
        Distortion::NONE
    );
    let e = Distortion::from_name("equidistant", &[]).unwrap_err();
    assert!(
        e.to_string()
            .contains("equidistant distortion needs 4 (k1, k2, k3, k4)"),
        "{e}"
    );
    let e = Distortion::from_name("plumb_bob", &eight).unwrap_err();
    assert!(
        e.to_string().contains("plumb_bob distortion needs 4 or 5"),
        "{e}"
    );
    let e = Distortion::from_name("kannala_brandt", &[0.0; 4]).unwrap_err();
    assert!(matches!(&e, PoseError::UnknownDistortionModel { name } if name == "kannala_brandt"));
    assert!(
        e.to_string()
            .contains("plumb_bob, rational_polynomial or equidistant"),
        "{e}"
    );

    // Names round-trip.
    for m in DistortionModel::ALL {
        assert_eq!(m.name().parse::<DistortionModel>().unwrap(), m);
        assert_eq!(m.to_string(), m.name());
        let zeros = vec![0.0; m.coefficient_names().len()];
        let d = Distortion::from_model(m, &zeros).unwrap();
        assert_eq!(d.model(), m);
        assert_eq!(d.coefficients(), zeros);
    }
}
