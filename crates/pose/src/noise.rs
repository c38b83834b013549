//! A pooled estimate of the corner noise behind pose fits, from their residuals.

/// A pooled estimate of a detector's corner noise from the reprojection residuals of recent
/// pose fits: the sums of the squared residuals and of their degrees of freedom, with
/// exponential forgetting, started from a prior. One fit's own estimate (`rms^2 N / (2N -
/// p)`) is noisy with few points; pooled over frames it is not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidualPool {
    sse: f64,
    dof: f64,
}

impl ResidualPool {
    /// The prior: a corner noise of `sigma_px` worth `dof` degrees of freedom.
    pub fn new(sigma_px: f64, dof: f64) -> Self {
        Self {
            sse: sigma_px.powi(2) * dof,
            dof,
        }
    }

    /// Adds one fit's residual (`rms_px` over `points` correspondences, `2 points -
    /// parameters` degrees of freedom), forgetting so that about `memory_dof` degrees of
    /// freedom are remembered; a fit without a residual degree of freedom, or with a
    /// non-finite residual, is skipped.
    pub fn add(&mut self, rms_px: f64, points: usize, parameters: usize, memory_dof: f64) {
        let Some((sse, dof)) = fit_sums(rms_px, points, parameters) else {
            return;
        };
        let keep = (1.0 - dof / memory_dof).max(0.0);
        self.sse = self.sse * keep + sse;
        self.dof = self.dof * keep + dof;
    }

    /// The pooled corner variance, px^2.
    pub fn variance(&self) -> f64 {
        self.sse / self.dof
    }
}

/// One fit's residual as the pool's sums: its squared residuals `rms^2 N` and its degrees of
/// freedom `2N - p`; `None` when it has no residual degree of freedom or a non-finite
/// residual (such a fit says nothing about the noise).
fn fit_sums(rms_px: f64, points: usize, parameters: usize) -> Option<(f64, f64)> {
    let dof = 2.0 * points as f64 - parameters as f64;
    (dof > 0.0 && rms_px.is_finite()).then_some((rms_px * rms_px * points as f64, dof))
}

/// The factor that takes a covariance the solvers scaled by one fit's own corner noise
/// (`max(rms^2 N / (2N - p), min_pixel_sigma^2)` over `N = points` correspondences and
/// `p = parameters`) to a corner noise of `variance` px^2. It is 1 when that scaling cannot
/// be undone or nothing better is known: no residual degree of freedom, a non-finite
/// residual, a zero scaling, or `variance` not finite and positive.
pub fn rescale_factor(
    variance: f64,
    rms_px: f64,
    points: usize,
    parameters: usize,
    min_pixel_sigma: f64,
) -> f64 {
    let Some((sse, dof)) = fit_sums(rms_px, points, parameters) else {
        return 1.0;
    };
    let floor = min_pixel_sigma * min_pixel_sigma;
    let used = (sse / dof).max(floor);
    if used > 0.0 && variance.is_finite() && variance > 0.0 {
        variance / used
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rescale_factor_undoes_the_solvers_own_scaling_and_is_one_when_it_cannot() {
        // rms 0.2 over 8 points, 6 parameters: own variance 0.04 * 8 / 10 = 0.032.
        let f = rescale_factor(0.25, 0.2, 8, 6, 0.1);
        assert!((f - 0.25 / 0.032).abs() < 1e-12, "{f}");
        // Below the floor the floor was used: 0.1^2.
        assert!((rescale_factor(0.25, 0.01, 8, 6, 0.1) - 25.0).abs() < 1e-9);
        assert_eq!(rescale_factor(0.25, 0.2, 3, 6, 0.1), 1.0);
        assert_eq!(rescale_factor(0.25, f64::NAN, 8, 6, 0.1), 1.0);
        assert_eq!(rescale_factor(f64::INFINITY, 0.2, 8, 6, 0.1), 1.0);
        assert_eq!(rescale_factor(0.25, 0.0, 8, 6, 0.0), 1.0);
    }

    #[test]
    fn the_pool_moves_from_its_prior_to_the_residuals_and_skips_what_has_no_residual() {
        let mut pool = ResidualPool::new(0.5, 10.0);
        assert!((pool.variance() - 0.25).abs() < 1e-12);
        pool.add(0.1, 3, 6, 100.0); // no residual degree of freedom
        pool.add(f64::NAN, 8, 6, 100.0);
        assert!((pool.variance() - 0.25).abs() < 1e-12);
        for _ in 0..200 {
            // rms 0.1 over 8 points, 10 dof: variance 0.01 * 8 / 10.
            pool.add(0.1, 8, 6, 100.0);
        }
        assert!(
            (pool.variance() - 0.008).abs() < 1e-4,
            "{}",
            pool.variance()
        );
    }
}
