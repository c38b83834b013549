//! Innovation tests: how far a candidate measurement lies from a filter's prediction, before
//! it is applied, to gate outliers or choose between candidates.

use nalgebra::{SMatrix, SVector};

use crate::space::Space;

/// The squared Mahalanobis distance of the innovation `y (-) y_pred` (in `space`, so angles
/// wrap) under the covariance `predicted + r`: the NIS the update would have, chi-square with
/// `M` degrees of freedom when the filter is consistent. `None` when `predicted + r` is not
/// positive definite or the distance is not finite.
pub fn innovation_nis<const M: usize, S: Space<M>>(
    space: &S,
    y: &SVector<f64, M>,
    y_pred: &SVector<f64, M>,
    predicted: &SMatrix<f64, M, M>,
    r: &SMatrix<f64, M, M>,
) -> Option<f64> {
    let nu = space.residual(y, y_pred);
    let s = predicted + r;
    let d2 = s.cholesky()?.solve(&nu).dot(&nu);
    d2.is_finite().then_some(d2)
}

/// A gate on the innovation test, with the rule that gives up on a track: each candidate
/// measurement is judged by its `d^2` against the filter's prediction and by the smallest
/// `d^2` against any one model's own prediction (for a single model, the same number).
///
/// - A measurement within [`threshold`](Self::threshold) of the prediction is accepted.
/// - One refused right after a refused one is accepted when some model's prediction explains
///   it (within the threshold): while one model holds nearly all of a mixture's probability,
///   a change another model predicts would otherwise be refused frame after frame. A single
///   outlying measurement is still refused.
/// - [`restart_due`](Self::restart_due) says when the refusals call for restarting the
///   filter from the latest measurement: [`restart_after`](Self::restart_after) in a row
///   beyond [`far_factor`](Self::far_factor) times the threshold of every model, or
///   [`persistent_factor`](Self::persistent_factor) times as many refused at all.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gate {
    /// The largest `d^2` accepted (e.g. a chi-square quantile for the measurement's
    /// dimension); `f64::INFINITY` accepts everything.
    pub threshold: f64,
    /// Refusals in a row, each beyond `far_factor` thresholds of every model, that call for a
    /// restart; 0 never restarts.
    pub restart_after: u32,
    /// How far beyond the threshold (as a factor on it) a refusal must lie to count towards
    /// `restart_after`: one just outside is more likely an unlucky measurement than a target
    /// every model has lost.
    pub far_factor: f64,
    /// Refusals in a row, as a factor on `restart_after`, that call for a restart however
    /// near the threshold they lay: a filter drifting just outside its gate is not followed
    /// back by any model.
    pub persistent_factor: u32,
}

/// What a [`Gate`] remembers of one filter's recent refusals.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GateRuns {
    /// Measurements refused in a row.
    pub refused: u32,
    /// Measurements refused in a row beyond [`Gate::far_factor`] thresholds of every model.
    pub far: u32,
}

impl Gate {
    /// Judges one measurement: `d2` against the filter's prediction, `best_model_d2` the
    /// smallest against one model's own prediction (at most `d2` when the mixture is one of
    /// the predictions tried). Returns whether it is accepted, and updates `runs`.
    pub fn judge(&self, runs: &mut GateRuns, d2: f64, best_model_d2: f64) -> bool {
        if d2 <= self.threshold || (best_model_d2 <= self.threshold && runs.refused > 0) {
            *runs = GateRuns::default();
            return true;
        }
        runs.refused += 1;
        if best_model_d2 > self.far_factor * self.threshold {
            runs.far += 1;
        } else {
            runs.far = 0;
        }
        false
    }

    /// Whether `runs` call for restarting the filter from the latest measurement.
    pub fn restart_due(&self, runs: &GateRuns) -> bool {
        self.restart_after > 0
            && (runs.far >= self.restart_after
                || runs.refused >= self.persistent_factor * self.restart_after)
    }
}

/// A factor on the measurement noise `R` learned from the innovations (adaptive `R`): after
/// each tested measurement of normalised innovation squared `d^2` (capped, so that one
/// outlier cannot blow it up), the factor `s` becomes `s (1 + (d^2 / dof - 1) / memory)`,
/// kept within `[min, max]`. It settles where the mean `d^2` is `dof`, the mean of a
/// chi-square with `dof` degrees of freedom: up when the innovations are larger than the
/// prediction and `R` together say (errors the reported `R` does not know), down when they
/// are not. `memory` is about the number of measurements it takes to follow a change.
///
/// A new scale may weigh its initial factor as only `prior` measurements
/// ([`NoiseScale::with_prior`]): the `n`-th measurement then moves it with a memory of
/// `min(memory, prior + n)`, a running mean at first and an exponential one once
/// `memory` measurements have been seen, so that a poor initial guess is forgotten within
/// a few measurements rather than within several memories.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseScale {
    factor: f64,
    memory: f64,
    min: f64,
    max: f64,
    /// The weight of what is known, in measurements (the initial factor's and those learned
    /// from); the effective memory until it reaches `memory`.
    weight: f64,
}

impl NoiseScale {
    /// Starts at `initial`, kept within `[min, max]`, with `memory` (at least 1) measurements
    /// of memory.
    pub fn new(initial: f64, memory: f64, min: f64, max: f64) -> Self {
        Self {
            factor: initial,
            memory,
            min,
            max,
            weight: memory,
        }
    }

    /// The same scale with its initial factor weighing `prior` measurements (at least 1, at
    /// most `memory`; by default it weighs `memory`).
    #[must_use]
    pub fn with_prior(mut self, prior: f64) -> Self {
        self.weight = prior.clamp(1.0, self.memory.max(1.0));
        self
    }

    /// The factor to put on `R`.
    pub fn factor(&self) -> f64 {
        self.factor
    }

    /// Learns from one measurement's `d^2`, capped at `cap`, for a measurement of `dof`
    /// dimensions. A non-finite `d^2` teaches nothing.
    pub fn learn(&mut self, d2: f64, cap: f64, dof: f64) {
        if !d2.is_finite() {
            return;
        }
        let ratio = d2.min(cap) / dof;
        let memory = (self.weight + 1.0).min(self.memory).max(1.0);
        let next = self.factor * (1.0 + (ratio - 1.0) / memory);
        self.factor = next.clamp(self.min, self.max);
        self.weight += 1.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{AngleMask, Euclidean};
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn the_distance_is_the_innovation_under_both_covariances() {
        let p = Matrix2::new(1.0, 0.0, 0.0, 4.0);
        let r = Matrix2::identity();
        let d2 = innovation_nis(
            &Euclidean,
            &Vector2::new(2.0, 5.0),
            &Vector2::new(0.0, 0.0),
            &p,
            &r,
        );
        // nu = (2, 5), S = diag(2, 5): 4/2 + 25/5.
        assert!((d2.unwrap_or(f64::NAN) - 7.0).abs() < 1e-12);
        // An angle across +-pi is a small innovation, not 2 pi.
        let mask = AngleMask::new([false, true]);
        let y = Vector2::new(0.0, 3.1);
        let d2 = innovation_nis(&mask, &y, &Vector2::new(0.0, -3.1), &p, &r).unwrap_or(f64::NAN);
        assert!(d2 < 0.01, "{d2}");
        // Not positive definite: no distance.
        let bad = Matrix2::new(-3.0, 0.0, 0.0, 1.0);
        assert_eq!(innovation_nis(&Euclidean, &y, &y, &bad, &r), None);
    }
    #[test]
    fn the_gate_takes_what_a_model_explains_after_a_refusal_and_restarts_on_far_runs() {
        let gate = Gate {
            threshold: 10.0,
            restart_after: 2,
            far_factor: 4.0,
            persistent_factor: 5,
        };
        let mut runs = GateRuns::default();
        assert!(gate.judge(&mut runs, 3.0, 3.0));
        // Refused once, even though a model explains it: a single outlier.
        assert!(!gate.judge(&mut runs, 12.0, 5.0));
        assert_eq!(runs, GateRuns { refused: 1, far: 0 });
        // Right after a refusal, a model's explanation is enough.
        assert!(gate.judge(&mut runs, 12.0, 5.0));
        assert_eq!(runs, GateRuns::default());
        // Far beyond every model twice in a row: restart.
        assert!(!gate.judge(&mut runs, 100.0, 50.0));
        assert!(!gate.restart_due(&runs));
        assert!(!gate.judge(&mut runs, 100.0, 50.0));
        assert!(gate.restart_due(&runs));
        // Just outside the gate of every model: ten in a row before a restart.
        let mut runs = GateRuns::default();
        for k in 1..=10 {
            assert!(!gate.judge(&mut runs, 12.0, 11.0));
            assert_eq!(gate.restart_due(&runs), k == 10, "{k}");
        }
        let never = Gate {
            restart_after: 0,
            ..gate
        };
        assert!(!never.restart_due(&runs));
    }

    #[test]
    fn the_noise_scale_settles_where_the_mean_nis_is_the_dimension() {
        let mut s = NoiseScale::new(2.0, 20.0, 0.5, 100.0);
        // Innovations 4 times what R says (d^2 = 4 dof at factor 1): d^2 falls as 1/s.
        for _ in 0..2000 {
            let d2 = 4.0 * 3.0 / s.factor();
            s.learn(d2, 16.0, 3.0);
        }
        assert!((s.factor() - 4.0).abs() < 1e-6, "{}", s.factor());
        // The cap bounds one outlier's effect; NaN teaches nothing; the bounds hold.
        let before = s.factor();
        s.learn(1e9, 16.0, 3.0);
        assert!((s.factor() - before * (1.0 + (16.0 / 3.0 - 1.0) / 20.0)).abs() < 1e-12);
        let before = s.factor();
        s.learn(f64::NAN, 16.0, 3.0);
        assert_eq!(s.factor(), before);
        for _ in 0..1000 {
            s.learn(0.0, 16.0, 3.0);
        }
        assert_eq!(s.factor(), 0.5);
    }

    #[test]
    fn a_light_prior_is_forgotten_within_a_few_measurements() {
        // Innovations a third of what R says at factor 1 (each measurement alone calls for
        // a factor of 1/3), starting from 2.
        let learn = |mut s: NoiseScale, n: usize| {
            for _ in 0..n {
                let d2 = 3.0 / 3.0 / s.factor();
                s.learn(d2, 16.0, 3.0);
            }
            s.factor()
        };
        let heavy = NoiseScale::new(2.0, 20.0, 0.1, 100.0);
        let light = heavy.with_prior(2.0);
        // The light prior is a running mean: after 10 measurements (2 x 2 + 10 / 3) / 12.
        let (l, h) = (learn(light, 10), learn(heavy, 10));
        assert!((l - (4.0 + 10.0 / 3.0) / 12.0).abs() < 1e-12, "light {l}");
        // The heavy one moves by 1/20 of the gap each time: 1/3 + (2 - 1/3) 0.95^10.
        assert!(
            (h - (1.0 / 3.0 + 5.0 / 3.0 * 0.95f64.powi(10))).abs() < 1e-12,
            "heavy {h}"
        );
        assert!(l < 0.62 && h > 1.3);
        // Both settle at the same place, and the light one then moves with `memory`: one
        // outlier moves it as much as the heavy one.
        let (mut l, mut h) = (light, heavy);
        for _ in 0..500 {
            l.learn(1.0 / l.factor(), 16.0, 3.0);
            h.learn(1.0 / h.factor(), 16.0, 3.0);
        }
        assert!((l.factor() - h.factor()).abs() < 1e-9);
        let (lb, hb) = (l.factor(), h.factor());
        l.learn(16.0, 16.0, 3.0);
        h.learn(16.0, 16.0, 3.0);
        assert!((l.factor() / lb - h.factor() / hb).abs() < 1e-12);
        assert!((l.factor() / lb - (1.0 + (16.0 / 3.0 - 1.0) / 20.0)).abs() < 1e-12);
    }
}
