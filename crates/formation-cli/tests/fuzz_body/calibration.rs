//! Camera files (OpenCV or ROS YAML, `pose::calib`): never a panic, and a calibration
//! that is accepted has a positive image size, finite intrinsics and passes its own size check.

/// Parses `data` as a calibration file and checks what it returns.
pub fn run(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(cal) = pose::Camera::from_yaml_str(&text) {
        assert!(
            cal.width > 0 && cal.height > 0,
            "accepted an empty image size"
        );
        let k = cal.intrinsics.matrix();
        assert!(
            k.iter().all(|v| v.is_finite()),
            "accepted non-finite intrinsics: {k}"
        );
        assert!(cal.check_size(cal.width, cal.height).is_ok());
    }
}
