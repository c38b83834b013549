//! Where each tracked leader will be at a coming frame: the filters' predictions, for
//! tracking-guided detection ([`crate::guided`]).

use nalgebra::Vector3;
use unicycle::Inputs;

use super::io::PredictedLeader;
use super::{Hypothesis, Tracker};

impl Tracker {
    /// Every live hypothesis of every track (a single-face start still being confirmed has
    /// two) predicted to a frame at `t` under the follower's inputs `follower`, in the same
    /// number of filter steps [`Tracker::update`] would take. Nothing changes in the
    /// tracker. A leader whose prediction fails (e.g. non-finite time) is left out.
    pub fn predict(&self, t: f64, follower: Inputs) -> Vec<PredictedLeader> {
        let mut out = Vec::with_capacity(self.tracks.len());
        let dt = self.config.filter.dt;
        let steps = match self.last_t {
            Some(prev) if t.is_finite() && t > prev => (((t - prev) / dt).round() as u64).max(1),
            Some(_) => return out,
            None => 1,
        };
        for (&robot, track) in &self.tracks {
            let coasting = self.last_t.is_some_and(|last| track.last_seen < last);
            for h in std::iter::once(&track.main).chain(track.rival.as_ref()) {
                if let Some((formation, std)) = predicted(h, steps, follower) {
                    out.push(PredictedLeader {
                        robot,
                        formation,
                        std,
                        coasting,
                    });
                }
            }
        }
        out
    }
}

/// A hypothesis's formation and standard deviations after `steps` predictions.
fn predicted(h: &Hypothesis, steps: u64, u: Inputs) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let mut f = h.filter.clone();
    for _ in 0..steps.min(1000) {
        f.predict_only(u).ok()?;
    }
    let m = f.formation();
    let y = Vector3::new(m.l12, m.alpha12, m.beta12);
    let s = f.formation_std();
    (y.iter().chain(s.iter()).all(|v| v.is_finite())).then_some((y, s))
}
