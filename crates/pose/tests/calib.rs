//! Camera files: OpenCV and ROS YAML, and malformed ones (fixtures/calibration).
#![cfg(feature = "calib")]

use pose::Camera;
use pose::calib::{CalibrationError, CalibrationFormat};
use pose::{Distortion, DistortionModel};
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/calibration")
        .join(name)
}

/// The format a fixture's text is read as.
fn format_of(name: &str) -> CalibrationFormat {
    let text = std::fs::read_to_string(fixture(name)).expect("the fixture is readable");
    Camera::from_yaml_str_with_format(&text)
        .expect("the fixture parses")
        .1
}

#[test]
fn opencv_file_loads() {
    let c = Camera::from_file(fixture("opencv_640x480.yaml")).unwrap();
    assert_eq!(format_of("opencv_640x480.yaml"), CalibrationFormat::OpenCv);
    assert_eq!((c.width, c.height), (640, 480));
    let k = c.intrinsics;
    assert!((k.alpha() - 554.256_258_422_040_8).abs() < 1e-9);
    assert!((k.beta() - 553.125).abs() < 1e-9);
    assert!((k.theta() - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert_eq!((k.u0(), k.v0()), (319.5, 239.5));
    assert_eq!(
        c.distortion,
        Distortion::plumb_bob(-0.12, 0.035, 0.001, -0.0005, 0.0).unwrap()
    );
}

#[test]
fn ros_file_loads_and_matches_the_opencv_one() {
    let ros = Camera::from_file(fixture("ros_camera_info.yaml")).unwrap();
    assert_eq!(format_of("ros_camera_info.yaml"), CalibrationFormat::Ros);
    let cv = Camera::from_file(fixture("opencv_640x480.yaml")).unwrap();
    assert_eq!((ros.width, ros.height), (cv.width, cv.height));
    assert!((ros.intrinsics.matrix() - cv.intrinsics.matrix()).amax() < 1e-9);
    assert_eq!(ros.distortion, cv.distortion);
}

#[test]
fn opencv_header_with_skew_and_no_distortion() {
    let text = "%YAML:1.0\n---\nimage_width: 100\nimage_height: 80\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 100., -5., 49.5, 0., 101., 39.5, 0., 0., 1. ]\n";
    let (c, format) = Camera::from_yaml_str_with_format(text).unwrap();
    assert_eq!(format, CalibrationFormat::OpenCv);
    assert!((c.intrinsics.matrix()[(0, 1)] + 5.0).abs() < 1e-12);
    assert!(c.distortion.is_identity());
}

#[test]
fn missing_camera_matrix_is_named() {
    let e = Camera::from_file(fixture("malformed_missing_camera_matrix.yaml")).unwrap_err();
    assert_eq!(
        e,
        CalibrationError::MissingField {
            field: "camera_matrix"
        }
    );
    assert!(e.to_string().contains("camera_matrix"));
}

#[test]
fn missing_width_is_named() {
    let e = Camera::from_file(fixture("malformed_missing_width.yaml")).unwrap_err();
    assert_eq!(
        e,
        CalibrationError::MissingField {
            field: "image_width"
        }
    );
}

#[test]
fn wrong_matrix_size_is_named() {
    let e = Camera::from_file(fixture("malformed_camera_matrix_shape.yaml")).unwrap_err();
    assert!(
        matches!(&e, CalibrationError::BadField { field: "camera_matrix", reason } if reason.contains("9 values")),
        "{e}"
    );
}

#[test]
fn singular_camera_matrix_is_named() {
    let e = Camera::from_file(fixture("malformed_singular_camera_matrix.yaml")).unwrap_err();
    assert!(
        matches!(
            &e,
            CalibrationError::BadField {
                field: "camera_matrix",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn invalid_yaml_is_reported() {
    let e = Camera::from_file(fixture("malformed_not_yaml.yaml")).unwrap_err();
    assert!(matches!(e, CalibrationError::Yaml { .. }), "{e}");
}

#[test]
fn missing_file_is_an_io_error() {
    let e = Camera::from_file(fixture("no_such_file.yaml")).unwrap_err();
    assert!(matches!(e, CalibrationError::Io { .. }), "{e}");
}

#[test]
fn unsupported_distortion_model_is_named() {
    let text = "image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\ndistortion_model: kannala_brandt8\ndistortion_coefficients: {rows: 1, cols: 4, data: [0.1, 0, 0, 0]}\n";
    let e = Camera::from_yaml_str(text).unwrap_err();
    assert!(
        matches!(
            e,
            CalibrationError::BadField {
                field: "distortion_model",
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn wrong_type_in_a_field_is_reported_with_its_name() {
    let text = "image_width: wide\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n";
    let e = Camera::from_yaml_str(text).unwrap_err();
    assert!(
        matches!(&e, CalibrationError::Yaml { message } if message.contains("image_width") || message.contains("line 1")),
        "{e}"
    );
}

#[test]
fn a_resized_image_gets_scaled_intrinsics_and_a_crop_is_refused() {
    let c = Camera::from_file(fixture("opencv_640x480.yaml")).unwrap();
    assert!(c.check_size(640, 480).is_ok());
    assert!(matches!(
        c.check_size(1280, 960),
        Err(CalibrationError::SizeMismatch {
            width: 1280,
            height: 960,
            calibrated_width: 640,
            calibrated_height: 480
        })
    ));
    // Twice the size: a point's pixel (pixel-centre convention) is (u + 1/2) 2 - 1/2.
    let big = c.scaled_to(1280, 960).unwrap();
    assert_eq!((big.width, big.height), (1280, 960));
    assert_eq!(big.distortion, c.distortion);
    let p = nalgebra::Point3::new(0.3, -0.2, 2.0);
    let (a, b) = (
        c.intrinsics.project(&p).unwrap(),
        big.intrinsics.project(&p).unwrap(),
    );
    assert!((b.x - ((a.x + 0.5) * 2.0 - 0.5)).abs() < 1e-9);
    assert!((b.y - ((a.y + 0.5) * 2.0 - 0.5)).abs() < 1e-9);
    // The identity scale changes nothing.
    assert_eq!(c.scaled_to(640, 480).unwrap(), c);
    // Another aspect ratio is a crop or another sensor mode, not a resize.
    for (w, h) in [(1280, 720), (0, 480), (640, 0)] {
        let e = c.scaled_to(w, h).unwrap_err();
        assert!(
            matches!(e, CalibrationError::NotAResize { .. }),
            "{w}x{h}: {e}"
        );
        assert!(e.to_string().contains(&format!("{w}x{h}")), "{e}");
    }
}

/// An OpenCV calibration of a 640x480 camera with the given matrix and distortion.
fn opencv_yaml(k: [f64; 9], d: &[f64]) -> String {
    let join = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {} ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: {}\n   dt: d\n   data: [ {} ]\n",
        join(&k),
        d.len(),
        join(d)
    )
}

#[test]
fn calibrations_no_camera_can_have_are_refused_with_the_field_named() {
    let k = |fx: f64, fy: f64, cx: f64, cy: f64| [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0];
    let ok = opencv_yaml(k(554.0, 554.0, 319.5, 239.5), &[-0.3, 0.1, 0.0, 0.0, -0.02]);
    assert!(Camera::from_yaml_str(&ok).is_ok());
    for (text, field, says) in [
        (
            opencv_yaml(k(1e-300, 554.0, 319.5, 239.5), &[0.0; 5]),
            "camera_matrix",
            "fx = 1e-300 px is not a focal length",
        ),
        (
            opencv_yaml(k(554.0, 1e9, 319.5, 239.5), &[0.0; 5]),
            "camera_matrix",
            "fy = 1e9 px",
        ),
        (
            opencv_yaml(k(554.0, 554.0, 5000.0, 239.5), &[0.0; 5]),
            "camera_matrix",
            "cx = 5000 px",
        ),
        (
            opencv_yaml(k(554.0, 554.0, 319.5, 239.5), &[-1e10, 0.0, 0.0, 0.0, 0.0]),
            "distortion_coefficients",
            "folds back",
        ),
        (
            opencv_yaml(k(554.0, 554.0, 319.5, 239.5), &[0.0, -1e10, 0.0, 0.0, 0.0]),
            "distortion_coefficients",
            "folds back",
        ),
        (
            opencv_yaml(k(554.0, 554.0, 319.5, 239.5), &[0.1, 0.2, 0.0]),
            "distortion_coefficients",
            "4 or 5 (plumb_bob: k1, k2, p1, p2[, k3]), 8 (rational_polynomial",
        ),
    ] {
        let e = Camera::from_yaml_str(&text).unwrap_err();
        match &e {
            CalibrationError::BadField { field: f, .. } => assert_eq!(*f, field, "{e}"),
            other => panic!("{other}"),
        }
        assert!(e.to_string().contains(says), "{e}");
    }
}

#[test]
fn rational_polynomial_files_load_in_both_formats() {
    let ros = Camera::from_file(fixture("ros_rational_polynomial.yaml")).unwrap();
    let cv = Camera::from_file(fixture("opencv_rational_1280x720.yaml")).unwrap();
    assert_eq!(
        (
            format_of("ros_rational_polynomial.yaml"),
            format_of("opencv_rational_1280x720.yaml")
        ),
        (CalibrationFormat::Ros, CalibrationFormat::OpenCv)
    );
    let expected =
        Distortion::rational_polynomial([0.1, -0.02, 0.0006, -0.0004, 0.001, 0.35, 0.01, 0.001])
            .unwrap();
    assert_eq!(ros.distortion, expected);
    assert_eq!(cv.distortion, expected);
    assert_eq!((ros.width, ros.height), (1280, 720));
}

#[test]
fn fisheye_files_load_in_both_formats() {
    let ros = Camera::from_file(fixture("ros_equidistant.yaml")).unwrap();
    let cv = Camera::from_file(fixture("opencv_fisheye_1280x800.yaml")).unwrap();
    let expected = Distortion::equidistant(0.05, -0.01, 0.002, -0.0003).unwrap();
    assert_eq!(ros.distortion, expected);
    assert_eq!(cv.distortion, expected);
    assert_eq!(
        format_of("opencv_fisheye_1280x800.yaml"),
        CalibrationFormat::OpenCv
    );
    assert!((ros.intrinsics.matrix() - cv.intrinsics.matrix()).amax() < 1e-12);
    // Without `fisheye_model: 1` the same four numbers are OpenCV's plumb bob: a fisheye file
    // must say what it is.
    let text = std::fs::read_to_string(fixture("opencv_fisheye_1280x800.yaml"))
        .unwrap()
        .replace("fisheye_model: 1\n", "");
    let plain = Camera::from_yaml_str(&text).unwrap();
    assert_eq!(plain.distortion.model(), DistortionModel::PlumbBob);
    // An OpenCV file may name the model as ROS does.
    let named = text.replace("image_width", "distortion_model: equidistant\nimage_width");
    assert_eq!(Camera::from_yaml_str(&named).unwrap().distortion, expected);
    // A contradiction is named.
    let both = std::fs::read_to_string(fixture("opencv_fisheye_1280x800.yaml"))
        .unwrap()
        .replace("image_width", "distortion_model: plumb_bob\nimage_width");
    let e = Camera::from_yaml_str(&both).unwrap_err();
    assert!(
        matches!(&e, CalibrationError::BadField { field: "distortion_model", reason } if reason.contains("fisheye_model")),
        "{e}"
    );
}

#[test]
fn lens_sanity_checks_hold_for_every_model() {
    let ros = |model: &str, d: &[f64]| {
        format!(
            "image_width: 1280\nimage_height: 800\ncamera_matrix: {{rows: 3, cols: 3, data: [430, 0, 639.5, 0, 430, 399.5, 0, 0, 1]}}\ndistortion_model: {model}\ndistortion_coefficients: {{rows: 1, cols: {}, data: [{}]}}\n",
            d.len(),
            d.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    // Sensible lenses of each model load.
    for (model, d) in [
        ("plumb_bob", &[-0.05, 0.01, 0.0, 0.0, 0.0][..]),
        (
            "rational_polynomial",
            &[0.3, 0.05, 0.0, 0.0, 0.0, 0.35, 0.04, 0.0][..],
        ),
        ("equidistant", &[0.05, -0.01, 0.002, -0.0003][..]),
    ] {
        let c = Camera::from_yaml_str(&ros(model, d)).unwrap();
        assert_eq!(c.distortion.model().name(), model);
    }
    // Profiles that fold back inside the image are refused, named by model.
    for (model, d, says) in [
        (
            "rational_polynomial",
            &[-2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][..],
            "folds back at normalised radius",
        ),
        (
            "rational_polynomial",
            &[0.0, 0.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0][..],
            "folds back at normalised radius 0.44",
        ),
        (
            "equidistant",
            &[-0.5, 0.0, 0.0, 0.0][..],
            "folds back at angle",
        ),
    ] {
        let e = Camera::from_yaml_str(&ros(model, d)).unwrap_err();
        match &e {
            CalibrationError::BadField { field, reason } => {
                assert_eq!(*field, "distortion_coefficients", "{e}");
                assert!(reason.contains(says) && reason.contains(model), "{e}");
            }
            other => panic!("{other}"),
        }
    }
    // An f-theta lens with a 100 px focal length would need rays beyond 180 degrees to fill a
    // 1280x800 image.
    let e = Camera::from_yaml_str(
        &ros("equidistant", &[0.0; 4])
            .replace("[430, 0, 639.5, 0, 430,", "[100, 0, 639.5, 0, 100,"),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("never reaches the image corner"),
        "{e}"
    );
    // A focal length no lens has is refused whatever the model.
    let e = Camera::from_yaml_str(
        &ros("equidistant", &[0.0; 4])
            .replace("[430, 0, 639.5, 0, 430,", "[1e-9, 0, 639.5, 0, 430,"),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("fx = 1e-9 px is not a focal length"),
        "{e}"
    );
    // The wrong count for a named model lists what that model takes.
    let e = Camera::from_yaml_str(&ros("equidistant", &[0.1, 0.0, 0.0, 0.0, 0.0])).unwrap_err();
    assert!(
        e.to_string()
            .contains("equidistant distortion needs 4 (k1, k2, k3, k4)"),
        "{e}"
    );
}

/// Radial distortion that is monotonic but no lens (#32): `k2 = 1e6` squeezed a 72-degree view
/// into 7 degrees and put a robot 2 m away at 14.3 m; `k2 = 1e300` gave no robot and no word.
#[test]
fn distortion_that_squeezes_or_stretches_the_view_is_refused() {
    let camera = |k2: &str| {
        format!(
            "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 554.256, 0., 319.5, 0., 554.256, 239.5, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ 0., {k2}, 0., 0., 0. ]\n"
        )
    };
    for (k2, shown) in [("1e6", "1000000.0"), ("1e300", "1e300"), ("1e3", "1000.0")] {
        let e = Camera::from_yaml_str(&camera(k2)).unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(
                &e,
                CalibrationError::BadField {
                    field: "distortion_coefficients",
                    ..
                }
            ) && text.contains("scales the image corner's ray by")
                && text.contains(shown),
            "k2 = {k2}: {text}"
        );
    }
    // Ordinary lenses pass: mild pincushion and barrel.
    for k2 in ["0.5", "-0.2", "2"] {
        Camera::from_yaml_str(&camera(k2)).unwrap();
    }
}

/// A non-finite matrix entry names its element and value (#32: "value 0 is not finite", where
/// 0 was the element's index).
#[test]
fn a_non_finite_entry_names_its_element_and_value() {
    let text = "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [554.0, 0.0, .nan, 0.0, 554.0, 239.5, 0.0, 0.0, 1.0]\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n";
    let e = Camera::from_yaml_str(text).unwrap_err().to_string();
    assert!(
        e.contains("camera_matrix") && e.contains("data[2] (row 0, column 2) is NaN"),
        "{e}"
    );
}
