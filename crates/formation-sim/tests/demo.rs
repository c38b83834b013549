//! The end-to-end demo, shortened: rendered frames, detection, pose and tracking through an
//! occlusion, open and closed loop, and a chain of three robots.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules); helpers here are test code too.

use formation_sim::demo::{DemoConfig, DemoError, run_demo};
use formation_tracker::tracker::{MeasurementUse, Status};

/// 4 s with a 0.5 s occlusion from 1.5 s, 2 x 2 samples per pixel (fast in tests).
fn short(closed_loop: bool, robots: usize) -> DemoConfig {
    let mut c = DemoConfig {
        robots,
        closed_loop,
        duration: 4.0,
        occlusion: Some((1.5, 2.0)),
        strip_every: 60,
        ..DemoConfig::default()
    };
    c.render.supersampling = 2;
    c
}

#[test]
fn open_loop_tracks_through_the_occlusion() {
    let run = run_demo(&short(false, 2)).unwrap();
    let s = &run.summary;
    assert_eq!(s.frames, 121);
    // The counts add up: every scored frame (after t = 0) is detected or hidden.
    assert_eq!(s.frames_scored, 120);
    assert_eq!(s.frames_scored, s.frames_detected + s.frames_occluded);
    assert_eq!(run.traces[0].records.len(), s.frames_scored);
    assert_eq!(s.frames_occluded, 15);
    // Seen in every frame outside the occlusion, coasting through it. `R` is the corner
    // noise the detector measures (no floor that dwarfs it), so the gate may refuse a few
    // frames outside the occlusion: about 0.1 % of consistent ones, more in the first
    // second, while `R` learns the errors the fit residuals miss (`innovation_memory`).
    assert_eq!(s.frames_detected, 120 - 15);
    assert!(
        (15..=15 + 3).contains(&s.frames_coasting),
        "{} frames coasting",
        s.frames_coasting
    );
    assert!(s.reacquired_same_id);
    assert_eq!(s.reacquired_after_s, Some(0.0));
    assert!(
        s.max_coasting_error_l12 < 0.05,
        "{}",
        s.max_coasting_error_l12
    );
    // Below the paper's figures.
    assert!(s.mse.l12 < 1.88e-4, "{}", s.mse.l12);
    assert!(s.mse.alpha12 < 7.22e-5, "{}", s.mse.alpha12);
    let records = &run.traces[0].records;
    for r in records {
        if r.occluded {
            assert_eq!(r.status, Some(Status::Coasting));
            assert_eq!(r.measurement, Some(MeasurementUse::Missing));
            assert!(r.step.measured[0].is_nan());
        } else if r.status != Some(Status::Tracking) {
            assert_eq!(r.status, Some(Status::Coasting), "t = {}", r.step.t);
            assert_eq!(
                r.measurement,
                Some(MeasurementUse::Gated),
                "t = {}",
                r.step.t
            );
        }
    }
    // Coasting: the standard deviation of l12 grows through the occlusion.
    let hidden: Vec<f64> = records
        .iter()
        .filter(|r| r.occluded)
        .map(|r| r.step.estimated_std[0])
        .collect();
    assert!(hidden.last().unwrap() > &(1.5 * hidden[0]));
    assert_eq!(run.strip.len(), 3);
    assert_eq!(run.strip[0].image.dimensions(), (640, 480));
}

#[test]
fn closed_loop_chain_keeps_the_formation() {
    let run = run_demo(&short(true, 3)).unwrap();
    assert_eq!(run.traces.len(), 2);
    assert_eq!((run.traces[1].follower, run.traces[1].leader), (3, 2));
    let s = &run.summary;
    // Every pair of the chain is reported, the reference pair (2 -> 1) first and equal to
    // the top-level figures.
    let pairs: Vec<(u32, u32)> = s.pairs.iter().map(|p| (p.follower, p.leader)).collect();
    assert_eq!(pairs, [(2, 1), (3, 2)]);
    assert_eq!(s.pairs[0].mse[0], s.mse.l12);
    assert_eq!(s.pairs[0].frames_detected, s.frames_detected);
    let p = &s.pairs[1];
    assert!(
        p.mse
            .iter()
            .chain(&p.mse_meas)
            .all(|m| m.is_finite() && *m >= 0.0)
    );
    assert!(p.mse[0] < 1e-3, "robot 3's l12 MSE {}", p.mse[0]);
    assert_eq!(p.frames_scored, run.traces[1].records.len());
    assert!(s.closed_loop);
    assert!(
        s.max_formation_error_after_3s < 0.1,
        "{}",
        s.max_formation_error_after_3s
    );
    // Robot 3 sees robot 2 all along (robot 1 is hidden only from robot 2), and its track is
    // never lost. Robot 2 starts from rest and is at 0.8 m/s one frame later, faster than
    // any model of the filter allows: that frame's measurement is refused and the next one
    // restarts the track (`TrackerConfig::restart_after_gated`). Robot 2 drives on its own
    // noisy estimates, so a few more frames are refused later (`docs/tracking.md`).
    let third = &run.traces[1].records;
    assert!(third.iter().all(|r| r.status != Some(Status::Lost)));
    assert_eq!(third[1].measurement, Some(MeasurementUse::Gated));
    assert_eq!(third[2].measurement, Some(MeasurementUse::Initialised));
    let coasting = third
        .iter()
        .filter(|r| r.status == Some(Status::Coasting))
        .count();
    assert!(
        coasting * 10 <= third.len(),
        "{coasting} of {} frames coasting",
        third.len()
    );
    // The restart bounds how long the track coasts: at most ten refused measurements in a
    // row (`restart_after_gated`, 2, five times over).
    let longest = third
        .iter()
        .fold((0, 0), |(run, longest), r| {
            let run = if r.status == Some(Status::Coasting) {
                run + 1
            } else {
                0
            };
            (run, longest.max(run))
        })
        .1;
    assert!(longest <= 10, "{longest} frames in a row coasting");
}

#[test]
fn bad_settings_are_errors() {
    let mut c = short(false, 1);
    assert!(matches!(
        run_demo(&c),
        Err(DemoError::Config { what: "robots", .. })
    ));
    c.robots = 2;
    c.dt = 0.0;
    assert!(matches!(
        run_demo(&c),
        Err(DemoError::Config { what: "dt", .. })
    ));
}

/// `run_demo_observed` hands out every follower's raw frame, in step order, with the inputs
/// the tracker was given: the test sequence `demo --save-frames` writes for `track`.
#[test]
fn observed_run_hands_out_every_raw_frame() {
    let mut c = short(false, 3);
    c.duration = 0.5;
    c.occlusion = None;
    let mut seen = Vec::new();
    let mut markers = Vec::new();
    let mut detector = fiducial::Detector::new(fiducial::DetectorConfig::default());
    let mut found = Vec::new();
    let run = formation_sim::demo::run_demo_observed(
        &c,
        |_, _| {},
        |f| {
            assert_eq!(f.image.dimensions(), (640, 480));
            assert!(f.inputs.v.is_finite() && f.inputs.w.is_finite());
            seen.push((f.step, f.robot));
            let view = fiducial::GrayView::new(f.image.as_raw(), 640, 480).unwrap();
            detector.detect(&view, &mut found);
            markers.push(found.len());
        },
    )
    .unwrap();
    let steps = (c.duration / c.dt).round() as usize;
    let want: Vec<(usize, usize)> = (0..=steps).flat_map(|s| [(s, 2), (s, 3)]).collect();
    assert_eq!(seen, want);
    // Raw frames, not annotated ones: the leader's markers read in every frame, as the demo's
    // own tracker read them.
    assert!(markers.iter().all(|&m| m > 0), "{markers:?}");
    assert_eq!(run.traces[0].records.len(), steps);
}

/// #30: a scenario's actuation and odometry reach the demo. With the follower's wheels at
/// 0.8 of the commanded speed it falls behind the leader, and the inputs handed out (what
/// its tracker is given) are its noisy odometry, not its commands.
#[test]
fn the_demo_follower_moves_by_its_actuation_and_reports_its_odometry() {
    let reference = include_str!("../../../fixtures/scenarios/reference.yaml");
    let run = |extra: &str| {
        let text = format!("{reference}{extra}");
        let spec = formation_sim::scenario_file::ScenarioSpec::parse(
            &text,
            false,
            std::path::Path::new("x.yaml"),
        )
        .unwrap();
        let mut c = DemoConfig::from_scenario(&spec);
        c.duration = 0.5;
        c.occlusion = None;
        c.render.supersampling = 1;
        let mut inputs = Vec::new();
        let run = formation_sim::demo::run_demo_observed(&c, |_, _| {}, |f| inputs.push(f.inputs))
            .unwrap();
        let last = run.traces[0].records.last().unwrap().step.truth;
        (last, inputs)
    };
    let (exact, exact_inputs) = run("");
    let (slow, slow_inputs) =
        run("actuation: {scale: [0.8, 1.0]}\nodometry_noise_std: [0.01, 0.01]\n");
    // 0.5 s at about 0.2 x 0.8 m/s less: the leader gets about 8 cm farther away.
    assert!(slow[0] - exact[0] > 0.03, "{slow} vs {exact}");
    assert_eq!(exact_inputs.len(), slow_inputs.len());
    // The odometry of the slow follower reports about 0.8 of what it was told, plus noise.
    let changed = exact_inputs
        .iter()
        .zip(&slow_inputs)
        .skip(1)
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(changed, exact_inputs.len() - 1);
}
