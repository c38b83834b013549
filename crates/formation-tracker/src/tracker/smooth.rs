//! Offline smoothing of a recorded run of the tracker.
//!
//! With [`Tracker::record_history`](super::Tracker::record_history) on, every filter step of
//! every hypothesis is copied into that hypothesis's history
//! ([`FormationFilter::record`](crate::filter::FormationFilter::record)): the track's first
//! estimate, each predict-only step of a frame gap, and each frame's step with the
//! measurement it applied (none when the leader was unseen, gated or invalid). A hypothesis
//! that loses to its rival takes its history with it. When a track is dropped its history is
//! kept as a finished *segment*; a robot seen again starts a new segment.
//!
//! [`Tracker::smooth`](super::Tracker::smooth) then runs
//! [`FormationFilter::smooth`](crate::filter::FormationFilter::smooth) over every segment
//! (finished or live) and reports one [`SmoothedLeader`] per frame of that segment, in
//! frame order. The smoother keeps the causal pass's decisions (which candidate, which
//! measurements passed the gate): it re-weighs what was accepted, it does not re-decide.

use serde::Serialize;
use unicycle::{Formation, Inputs};

use crate::filter::{FilterStep, FormationFilter};

/// One recorded filter step; `frame` is the frame time if the step ended a frame (the
/// predict-only steps of a frame gap have `None`).
#[derive(Debug, Clone, Copy)]
pub(super) struct Recorded {
    pub(super) frame: Option<f64>,
    pub(super) step: FilterStep,
}

/// The recorded steps of one track, from its start to its end (or to now).
#[derive(Debug, Clone)]
pub(super) struct Segment {
    pub(super) robot: u32,
    pub(super) steps: Vec<Recorded>,
}

/// One leader in one frame, smoothed over the whole recording.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SmoothedLeader {
    /// Frame time, seconds.
    pub t: f64,
    /// Robot id.
    pub robot: u32,
    /// Index of the track segment this frame belongs to (0 for the first track of any robot,
    /// counted over all robots in the order the segments ended; a robot lost and seen again
    /// has two segments).
    pub segment: usize,
    /// Whether a measurement of this leader was applied in this frame (`false`: coasting,
    /// the estimate is interpolated by the smoother from the frames around it).
    pub measured: bool,
    /// Smoothed formation: separation `l12` (m), bearings `alpha12` in the leader's frame
    /// and `beta12` in the follower's (rad); flat in JSON.
    #[serde(flatten)]
    pub formation: Formation,
    /// Smoothed leader speed over the frame step that ended at `t`, m/s.
    pub v1: f64,
    /// Smoothed leader turn rate over the frame step that ended at `t`, rad/s.
    pub w1: f64,
    /// Standard deviation of `l12`, m.
    pub l12_std: f64,
    /// Standard deviation of `alpha12`, rad.
    pub alpha12_std: f64,
    /// Standard deviation of `beta12`, rad.
    pub beta12_std: f64,
    /// Standard deviation of `v1`, m/s.
    pub v1_std: f64,
    /// Standard deviation of `w1`, rad/s.
    pub w1_std: f64,
}

impl Segment {
    /// The smoothed frames of this segment, tagged with `index`.
    pub(super) fn smooth(
        &self,
        index: usize,
        template: &FormationFilter,
    ) -> Result<Vec<SmoothedLeader>, crate::filter::FilterError> {
        let steps: Vec<FilterStep> = self.steps.iter().map(|r| r.step).collect();
        let smoothed = template.smooth(&steps)?;
        Ok(self
            .steps
            .iter()
            .zip(&smoothed)
            .filter_map(|(r, s)| {
                let t = r.frame?;
                let f = s.formation();
                let fs = s.formation_std();
                let vs = s.velocity_std();
                Some(SmoothedLeader {
                    t,
                    robot: self.robot,
                    segment: index,
                    measured: r.step.measurement.is_some(),
                    formation: f,
                    v1: s.velocity.v,
                    w1: s.velocity.w,
                    l12_std: fs[0],
                    alpha12_std: fs[1],
                    beta12_std: fs[2],
                    v1_std: vs[0],
                    w1_std: vs[1],
                })
            })
            .collect())
    }
}

/// The inputs of a track's first step (nothing was applied before it).
pub(super) const NO_INPUTS: Inputs = Inputs { v: 0.0, w: 0.0 };
