//! Every usage error exits with code 2 and names the option and the value
//! (`docs/reliability.md`; issue #32 found 22 that exited 1, among them `--mount nan,0.3`,
//! `markers --ids 5-3`, an unknown `--dictionary` and `render --paper-fig 12`).

#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

mod common;

#[test]
fn usage_errors_exit_2_and_name_the_option_and_value() {
    let d = common::blank_frames("usage");
    let fixture = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/reference.yaml"
    );
    let cases: &[(&[&str], &str)] = &[
        (
            &[
                "detect",
                "--camera",
                "camera.yaml",
                "--mount",
                "nan,0.3",
                "frames/f0.png",
            ],
            "--mount nan,0.3: OFFSET `nan`",
        ),
        (
            &[
                "detect",
                "--camera",
                "camera.yaml",
                "--mount",
                "0.5",
                "frames/f0.png",
            ],
            "expected OFFSET,HEIGHT",
        ),
        (
            &[
                "detect",
                "--camera",
                "camera.yaml",
                "--mount",
                "0.5,-1",
                "frames/f0.png",
            ],
            "HEIGHT `-1`",
        ),
        (
            &[
                "detect",
                "--camera",
                "camera.yaml",
                "--mount",
                "0.5,0.3,30",
                "frames/f0.png",
            ],
            "did you mean 30 degrees",
        ),
        (
            &["detect", "--mount", "0.5,0.3", "frames/f0.png"],
            "need --camera FILE",
        ),
        (
            &["detect", "--dictionary", "tag99h99", "frames/f0.png"],
            "--dictionary tag99h99",
        ),
        (&["detect", "--pan", "30", "frames/f0.png"], "--pan"),
        (
            &[
                "markers",
                "--out",
                "m",
                "--dictionary",
                "tag36h11",
                "--ids",
                "5-3",
            ],
            "--ids 5-3",
        ),
        (
            &[
                "markers",
                "--out",
                "m",
                "--dictionary",
                "tag36h11",
                "--ids",
                "0-999",
            ],
            "beyond the dictionary",
        ),
        (
            &[
                "markers",
                "--out",
                "m",
                "--dictionary",
                "nope",
                "--ids",
                "1",
            ],
            "--dictionary nope",
        ),
        (
            &[
                "markers",
                "--out",
                "m",
                "--dictionary",
                "tag36h11",
                "--ids",
                "1",
                "--size-mm=-1",
            ],
            "--size-mm",
        ),
        (&["markers", "--out", "m", "--robots", "0"], "--robots"),
        (
            &["markers", "--out", "m", "--robots", "100000"],
            "--robots 100000 is more than",
        ),
        (
            &["markers", "--out", "m", "--px-per-cell", "0"],
            "--px-per-cell",
        ),
        (
            &[
                "detect",
                "--camera",
                "camera.yaml",
                "--marker-size",
                "1e308",
                "frames/f0.png",
            ],
            "not a printed marker's",
        ),
        (
            &["render", "--paper-fig", "12", "--out", "x.png"],
            "--paper-fig",
        ),
        (&["track", "frames"], "--camera FILE is required"),
        (
            &[
                "track",
                "frames",
                "--camera",
                "camera.yaml",
                "--image-topic",
                "/a",
            ],
            "--image-topic",
        ),
        (
            &["demo", "--robots", "3", "--scenario", fixture, "--out", "o"],
            "--robots 3 with --scenario",
        ),
        (&["--max-memory", "1KiB", "info"], "--max-memory"),
        (&["--max-memory", "lots", "info"], "--max-memory"),
    ];
    for (args, says) in cases {
        let out = common::run(&d, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert_eq!(
            stderr
                .trim()
                .lines()
                .filter(|l| l.contains("error"))
                .count(),
            1,
            "{args:?}: {stderr}"
        );
        assert!(!d.join("m").exists() && !d.join("o").exists() && !d.join("x.png").exists());
    }
}
