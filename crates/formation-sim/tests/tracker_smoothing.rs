//! Offline smoothing of a recorded tracker run (`Tracker::record_history`,
//! `Tracker::smooth`) on the reference scenario with simulated pose measurements: one
//! smoothed estimate per frame, better than the causal track, through an occlusion and
//! across a loss.
#![allow(clippy::unwrap_used)] // Tests may unwrap (house rules).

use formation_sim::scenario::{ScenarioConfig, simulate};
use formation_tracker::mount::CameraMount;
use formation_tracker::tracker::{
    FrameInput, LeaderReport, Observation, PoseMeasurement, SmoothedLeader, Status, Tracker,
    TrackerConfig,
};
use nalgebra::{Matrix6, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use unicycle::{Inputs, PolarModel, wrap_angle};

mod common;
use common::camera_pose;

const ROBOT: u32 = 4;
const POSE_STD: [f64; 6] = [0.01, 0.01, 0.01, 0.005, 0.005, 0.01];

struct Frame {
    t: f64,
    truth: Vector3<f64>,
    leader_velocity: Inputs,
    follower: Inputs,
    pose: pose::Pose,
}

fn frames(seed: u64) -> Vec<Frame> {
    let scenario = simulate(&ScenarioConfig::reference(seed)).unwrap();
    let mount = CameraMount::default();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = Normal::new(0.0, 1.0).unwrap();
    let mut out = Vec::new();
    for (k, s) in scenario.samples.iter().enumerate() {
        let prev = &scenario.samples[k.saturating_sub(1)];
        let true_pose = camera_pose(&PolarModel::leader_pose(&s.truth), &s.follower, &mount);
        let mut p = true_pose.to_params();
        for (i, sd) in POSE_STD.iter().enumerate() {
            p[i] += sd * n.sample(&mut rng);
        }
        out.push(Frame {
            t: s.t,
            truth: PolarModel::h(&s.truth),
            leader_velocity: prev.leader_inputs,
            follower: prev.follower_inputs,
            pose: pose::Pose::from_params(&p),
        });
    }
    out
}

fn observation(pose: pose::Pose) -> Observation {
    Observation {
        robot: ROBOT,
        points: 8,
        pose: PoseMeasurement::Chosen(pose::Estimate {
            pose,
            rms: 0.3,
            covariance: Matrix6::from_diagonal(&Vector6::from_iterator(
                POSE_STD.iter().map(|s| s * s),
            )),
            iterations: 4,
            converged: true,
        }),
    }
}

/// Runs the tracker (recording if `record`) with the leader hidden while `hidden(t)`;
/// returns the tracker, the frames and the causal report of each frame (if any).
fn run(
    seed: u64,
    record: bool,
    hidden: impl Fn(f64) -> bool,
) -> (Tracker, Vec<Frame>, Vec<Option<LeaderReport>>) {
    let frames = frames(seed);
    let mut config = TrackerConfig::reference(0.5, 1.0 / 30.0);
    config.corner_sigma_px = None;
    let mut tracker = Tracker::new(config).unwrap();
    tracker.record_history(record);
    let mut reports = Vec::new();
    for f in &frames {
        let observations = if hidden(f.t) {
            vec![]
        } else {
            vec![observation(f.pose)]
        };
        let report = tracker
            .update(&FrameInput {
                t: f.t,
                follower: f.follower,
                mount: CameraMount::default(),
                observations,
            })
            .unwrap();
        reports.push(report.leaders.first().copied());
    }
    (tracker, frames, reports)
}

fn l12_error(l12: f64, f: &Frame) -> f64 {
    l12 - f.truth[0]
}

fn alpha_error(alpha: f64, f: &Frame) -> f64 {
    wrap_angle(alpha - f.truth[1])
}

fn finite(s: &SmoothedLeader) -> bool {
    [
        s.formation.l12,
        s.formation.alpha12,
        s.formation.beta12,
        s.v1,
        s.w1,
        s.l12_std,
        s.alpha12_std,
        s.beta12_std,
        s.v1_std,
        s.w1_std,
    ]
    .iter()
    .all(|v| v.is_finite())
}

#[test]
fn smoothing_beats_the_causal_track_and_bridges_an_occlusion() {
    let hidden = |t: f64| (3.0..4.0).contains(&t);
    let (tracker, frames, causal) = run(2, true, hidden);
    let smoothed = tracker.smooth().unwrap();
    assert_eq!(
        smoothed.len(),
        frames.len(),
        "one smoothed estimate per frame"
    );
    let (mut c_l, mut s_l, mut c_a, mut s_a) = (0.0, 0.0, 0.0, 0.0);
    let (mut c_v, mut s_v, mut late) = (0.0, 0.0, 0);
    let (mut c_gap, mut s_gap): (f64, f64) = (0.0, 0.0);
    for ((f, c), s) in frames.iter().zip(&causal).zip(&smoothed) {
        let c = c.as_ref().unwrap();
        assert!((s.t - f.t).abs() < 1e-12);
        assert_eq!((s.robot, s.segment), (ROBOT, 0));
        assert!(finite(s));
        assert_eq!(s.measured, !hidden(f.t) && f.t > 0.0);
        c_l += l12_error(c.formation.l12, f).powi(2);
        s_l += l12_error(s.formation.l12, f).powi(2);
        c_a += alpha_error(c.formation.alpha12, f).powi(2);
        s_a += alpha_error(s.formation.alpha12, f).powi(2);
        if f.t > 2.0 {
            c_v += (c.v1 - f.leader_velocity.v).powi(2);
            s_v += (s.v1 - f.leader_velocity.v).powi(2);
            late += 1;
        }
        if hidden(f.t) {
            assert_eq!(c.status, Status::Coasting);
            c_gap = c_gap.max(l12_error(c.formation.l12, f).abs());
            s_gap = s_gap.max(l12_error(s.formation.l12, f).abs());
        }
    }
    assert!(late > 100);
    assert!(s_l < 0.5 * c_l, "l12: smoothed {s_l} vs causal {c_l}");
    assert!(s_a < 0.5 * c_a, "alpha12: smoothed {s_a} vs causal {c_a}");
    assert!(s_v < c_v, "v1 after 2 s: smoothed {s_v} vs causal {c_v}");
    assert!(
        s_gap < c_gap,
        "occlusion: smoothed {s_gap} vs causal {c_gap}"
    );
}

#[test]
fn a_lost_track_and_its_successor_are_two_segments() {
    // Hidden for 3 s: lost after 2 s, re-initialised at 5 s.
    let (tracker, frames, causal) = run(3, true, |t| (2.0..5.0).contains(&t));
    let smoothed = tracker.smooth().unwrap();
    let first: Vec<_> = smoothed.iter().filter(|s| s.segment == 0).collect();
    let second: Vec<_> = smoothed.iter().filter(|s| s.segment == 1).collect();
    assert_eq!(first.len() + second.len(), smoothed.len());
    assert!(smoothed.iter().all(|s| s.robot == ROBOT && finite(s)));
    // The first segment ends before the frame that reported the loss (at 4 s), the second
    // starts at re-acquisition (5 s); the frames between have no track.
    let lost_at = frames
        .iter()
        .zip(&causal)
        .find(|(_, c)| c.is_some_and(|c| c.status == Status::Lost))
        .map(|(f, _)| f.t)
        .unwrap();
    assert!(first.last().unwrap().t < lost_at);
    assert!((second.first().unwrap().t - 5.0).abs() < 0.02);
    let tracked = causal
        .iter()
        .filter(|c| c.is_some_and(|c| c.status != Status::Lost))
        .count();
    assert_eq!(smoothed.len(), tracked);
}

#[test]
fn nothing_is_smoothed_without_recording() {
    let (tracker, _, _) = run(1, false, |_| false);
    assert!(tracker.smooth().unwrap().is_empty());
}
