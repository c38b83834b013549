//! The follower-inputs CSV: columns in any order, hold between rows, typed errors.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use formation_io::inputs::{FollowerInputs, InputsError, Key};
use proptest::prelude::*;

#[test]
fn frame_keyed_rows_hold_until_the_next() {
    let csv = "# follower\npan, w2, frame, v2, note\n0.1, 0.0, 0, 0.0, a\n0.2, 0.05, 3, 0.4, b\n";
    let f = FollowerInputs::parse(csv).unwrap();
    assert_eq!(f.key(), Key::Frame);
    assert_eq!(f.len(), 2);
    let s = f.at(2, 99.0).unwrap();
    assert_eq!((s.inputs.v, s.inputs.w, s.pan), (0.0, 0.0, Some(0.1)));
    let s = f.at(3, 0.0).unwrap();
    assert_eq!((s.inputs.v, s.inputs.w, s.pan), (0.4, 0.05, Some(0.2)));
    assert_eq!(f.at(1000, 0.0).unwrap().inputs.v, 0.4);
}

#[test]
fn time_keyed_rows_without_pan() {
    let f = FollowerInputs::parse("t,v2,w2\n0.5,1,2\n1.0,3,4\n").unwrap();
    assert_eq!(f.key(), Key::Time);
    assert!(f.at(0, 0.4).is_none(), "before the first row");
    let s = f.at(0, 0.5).unwrap();
    assert_eq!((s.inputs.v, s.pan), (1.0, None));
    // A frame time computed as k / fps lands within rounding of the row.
    assert_eq!(f.at(0, 1.0 - 1e-12).unwrap().inputs.v, 3.0);
    assert_eq!(f.at(0, 0.99).unwrap().inputs.v, 1.0);
}

#[test]
fn a_byte_order_mark_is_not_part_of_the_first_column() {
    let f = FollowerInputs::parse("\u{feff}frame,v2,w2\n0,0.5,0.1\n").unwrap();
    assert_eq!(f.key(), Key::Frame);
    assert_eq!(f.at(0, 0.0).unwrap().inputs.v, 0.5);
}

#[test]
fn bad_files_are_typed_errors() {
    let e = |s: &str| FollowerInputs::parse(s).unwrap_err();
    assert!(matches!(e(""), InputsError::Empty));
    assert!(matches!(e("frame,v2,w2\n"), InputsError::Empty));
    assert!(matches!(e("v2,w2\n1,2\n"), InputsError::Header { .. }));
    assert!(matches!(e("t,frame,v2,w2\n"), InputsError::Header { .. }));
    assert!(matches!(e("frame,w2\n1,2\n"), InputsError::Header { .. }));
    assert!(matches!(
        e("frame,v2,w2\n0,1,nan\n"),
        InputsError::BadValue { line: 2, .. }
    ));
    // A frame number is a whole number, and the message says so.
    for bad in ["0.5", "-1", "x", "1e3"] {
        let err = e(&format!("frame,v2,w2\n{bad},1,1\n"));
        assert!(
            matches!(err, InputsError::BadFrame { line: 2, .. }),
            "{bad}: {err}"
        );
        assert!(err.to_string().contains("whole number"), "{err}");
    }
    // Extra fields are an error, like missing ones (a stray comma shifts every column).
    assert!(matches!(
        e("frame,v2,w2\n0,1,2,3\n"),
        InputsError::ShortRow {
            line: 2,
            found: 4,
            expected: 3
        }
    ));
    // A column named twice is ambiguous.
    let dup = e("frame,v2,w2,V2\n0,1,2,3\n");
    assert!(matches!(dup, InputsError::DuplicateColumn { .. }), "{dup}");
    assert!(dup.to_string().contains("`V2` appears twice"), "{dup}");
    assert!(matches!(
        e("frame,v2,w2\n0,1\n"),
        InputsError::ShortRow { line: 2, .. }
    ));
    assert!(matches!(
        e("t,v2,w2\n1,0,0\n# c\n1,0,0\n"),
        InputsError::NotIncreasing { line: 4, .. }
    ));
    assert!(matches!(
        FollowerInputs::from_path(std::path::Path::new("/nonexistent/inputs.csv")),
        Err(InputsError::Io { .. })
    ));
}

proptest! {
    /// The sample for a frame is the row with the largest key at or before it.
    #[test]
    fn lookup_is_the_last_row_at_or_before(
        gaps in proptest::collection::vec(1u64..5, 1..20),
        probe in 0u64..120,
    ) {
        let mut keys = Vec::new();
        let mut k = 0;
        for g in &gaps {
            k += g;
            keys.push(k);
        }
        let mut csv = String::from("frame,v2,w2\n");
        for (i, k) in keys.iter().enumerate() {
            csv += &format!("{k},{i},0\n");
        }
        let f = FollowerInputs::parse(&csv).unwrap();
        let want = keys.iter().rposition(|k| *k <= probe);
        let got = f.at(probe, 0.0).map(|s| s.inputs.v as usize);
        prop_assert_eq!(got, want);
    }
}

/// Odometry that no follower can have is refused, naming the file, line, column and value
/// (#32: `v = 1e300` was accepted and reset the track every other frame).
#[test]
fn impossible_speeds_in_the_inputs_csv_are_refused() {
    let dir = std::env::temp_dir().join(format!("ft-inputs-speed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (row, column, says) in [
        ("1,1e300,0", "v2", "1e300 is outside -20 to 20 m/s"),
        ("1,0.5,-25", "w2", "-25.0 is outside -20 to 20 rad/s"),
        ("1,0.5,0,30", "pan", "30.0 is outside -pi to pi rad"),
    ] {
        let path = dir.join(format!("{column}.csv"));
        std::fs::write(
            &path,
            format!(
                "frame,v2,w2,pan\n0,0,0,0\n{row}{}\n",
                if column == "pan" { "" } else { ",0" }
            ),
        )
        .unwrap();
        let e = formation_io::inputs::FollowerInputs::from_path(&path)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&path.display().to_string())
                && e.contains(&format!("line 3, column {column}"))
                && e.contains(says),
            "{e}"
        );
    }
}
