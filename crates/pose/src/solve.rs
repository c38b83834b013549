//! The public solver: input checks, the choice POSIT + LM (non-coplanar) or IPPE (both
//! candidates) + LM (coplanar), and the result with its covariance.

use crate::lm::{self, LmConfig, Normal};
use unicycle::PlanarPose;

use crate::plane::{PlanarEstimate, PlaneFrame, PlaneReprojection};
use crate::{Distortion, Intrinsics, Pose, PoseError, ippe, posit};
use nalgebra::{Matrix3, Matrix6, Point2, Point3, SymmetricEigen, Vector3};

/// Correspondence counts up to this undistort into a stack buffer; more use the heap.
const STACK_POINTS: usize = 32;

/// Solver settings. `Default` gives the documented defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Levenberg-Marquardt settings.
    pub lm: LmConfig,
    /// Levenberg-Marquardt settings of [`PoseSolver::refine_on_plane`]. Default: those of
    /// `lm` with `relative_cost_tolerance` 1e-12: three parameters from a start near the
    /// minimum converge in a few iterations, so the refinement runs to the minimum within
    /// rounding (a caller derives other quantities from it and compares candidates).
    pub plane_lm: LmConfig,
    /// Floor on the pixel noise standard deviation used to scale the covariance (pixels).
    /// Default 0.1 px: a noise-free solve (residual ~0) still reports the uncertainty of a
    /// good corner detector instead of a zero covariance.
    pub min_pixel_sigma: f64,
    /// Model points whose RMS distance from their best-fit plane is below this fraction of
    /// their RMS spread in the plane are treated as coplanar (IPPE path). Default 1e-3
    /// (0.1 mm on a 10 cm face).
    pub planarity_tolerance: f64,
    /// Model points whose spread across their best-fit line is below this fraction of the
    /// spread along it are rejected as collinear. Default 1e-6.
    pub collinearity_tolerance: f64,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            lm: LmConfig::default(),
            plane_lm: LmConfig {
                relative_cost_tolerance: 1e-12,
                ..LmConfig::default()
            },
            min_pixel_sigma: 0.1,
            planarity_tolerance: 1e-3,
            collinearity_tolerance: 1e-6,
        }
    }
}

/// One refined pose with its quality figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Model (rig) frame to camera frame.
    pub pose: Pose,
    /// Reprojection RMS in pixels, `sqrt(sum |e_i|^2 / N)` over the N points.
    pub rms: f64,
    /// Covariance of `[wx, wy, wz, tx, ty, tz]`: `sigma^2 (J^T J)^-1` with `J` the 2N x 6
    /// reprojection Jacobian at the optimum and
    /// `sigma^2 = max(sum |e_i|^2 / (2N - 6), min_pixel_sigma^2)`.
    pub covariance: Matrix6<f64>,
    /// Levenberg-Marquardt iterations used.
    pub iterations: usize,
    /// False when LM ran out of iterations (only possible for an alternative candidate; a
    /// best pose that does not converge is an error).
    pub converged: bool,
}

/// The result of [`PoseSolver::solve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolution {
    /// The pose with the lowest reprojection error.
    pub best: Estimate,
    /// For coplanar points, the other IPPE candidate after its own refinement (it may have
    /// converged to the same minimum when the view is not ambiguous). `None` for non-coplanar
    /// points or when the other candidate could not be refined.
    pub alternative: Option<Estimate>,
    /// Whether the model points were treated as coplanar.
    pub coplanar: bool,
}

impl PoseSolution {
    /// The best pose.
    pub fn pose(&self) -> Pose {
        self.best.pose
    }

    /// The best pose's reprojection RMS in pixels.
    pub fn rms(&self) -> f64 {
        self.best.rms
    }

    /// How ambiguous the view was: the alternative's RMS over the best's (>= 1; close to 1 means
    /// the flip is nearly as good as the chosen pose). `None` without an alternative or when
    /// the alternative is the same pose (rotation within 1e-6 rad).
    pub fn ambiguity_ratio(&self) -> Option<f64> {
        let alt = self.alternative?;
        if alt.pose.rotation_angle_to(&self.best.pose) < 1e-6 {
            return None;
        }
        Some(alt.rms / self.best.rms.max(f64::MIN_POSITIVE))
    }
}

/// The pose solver: intrinsics, an optional distortion model applied to the image points, and
/// options. Cheap to build and `Copy`; keep one per camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseSolver {
    intrinsics: Intrinsics,
    distortion: Option<Distortion>,
    options: SolverOptions,
}

/// Shape of a validated model.
#[derive(Debug, Clone, Copy)]
struct Geometry {
    coplanar: bool,
    centroid: Vector3<f64>,
    /// Columns: principal axes, largest spread first, third = normal (a proper rotation).
    frame: Matrix3<f64>,
}

/// Image points after undistortion, on the stack when few (the size difference between the
/// variants is the point: no heap allocation for up to `STACK_POINTS` points).
#[allow(clippy::large_enum_variant)]
enum Pixels<'a> {
    Borrowed(&'a [Point2<f64>]),
    Stack([Point2<f64>; STACK_POINTS], usize),
    Heap(Vec<Point2<f64>>),
}

impl Pixels<'_> {
    fn as_slice(&self) -> &[Point2<f64>] {
        match self {
            Pixels::Borrowed(s) => s,
            Pixels::Stack(a, n) => &a[..*n],
            Pixels::Heap(v) => v,
        }
    }
}

impl PoseSolver {
    /// A solver for undistorted pixels with default options.
    pub fn new(intrinsics: Intrinsics) -> Self {
        Self {
            intrinsics,
            distortion: None,
            options: SolverOptions::default(),
        }
    }

    /// Undistort image points with this model before solving (a model that is the identity,
    /// see [`Distortion::is_identity`], is skipped).
    pub fn with_distortion(mut self, distortion: Distortion) -> Self {
        self.distortion = if distortion.is_identity() {
            None
        } else {
            Some(distortion)
        };
        self
    }

    /// Replace the options.
    pub fn with_options(mut self, options: SolverOptions) -> Self {
        self.options = options;
        self
    }

    /// The intrinsics.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// The options.
    pub fn options(&self) -> &SolverOptions {
        &self.options
    }

    /// Pose from model points (rig frame) and their pixels. Non-coplanar points: POSIT, then
    /// LM. Coplanar points: IPPE's two candidates, each refined by LM; the better is `best`,
    /// the other `alternative`.
    pub fn solve(
        &self,
        model: &[Point3<f64>],
        image: &[Point2<f64>],
    ) -> Result<PoseSolution, PoseError> {
        let geo = self.validate(model, image)?;
        let pixels = self.undistort(image)?;
        let px = pixels.as_slice();
        if geo.coplanar {
            let [a, b] = self.planar_refined(model, px, &geo)?;
            return Ok(PoseSolution {
                best: a,
                alternative: Some(b),
                coplanar: true,
            });
        }
        let init = match posit::posit(&self.intrinsics, model, px) {
            Ok(p) => p,
            Err(PoseError::NotConverged { estimate, .. }) => estimate,
            Err(PoseError::Degenerate { .. }) => {
                // Nearly coplanar: start from the best-fit plane's IPPE candidates instead.
                let [a, _] = self.planar_refined(model, px, &geo)?;
                return Ok(PoseSolution {
                    best: a,
                    alternative: None,
                    coplanar: false,
                });
            }
            Err(e) => return Err(e),
        };
        match self.refine_checked(model, px, &init) {
            Ok(best) => Ok(PoseSolution {
                best,
                alternative: None,
                coplanar: false,
            }),
            // A poor POSIT start (noisy, nearly planar points) can put points behind the camera
            // or leave LM crawling: retry from the best-fit plane's IPPE candidates.
            Err(first @ (PoseError::PointBehindCamera { .. } | PoseError::NotConverged { .. })) => {
                match self.planar_refined(model, px, &geo) {
                    Ok([best, _]) => Ok(PoseSolution {
                        best,
                        alternative: None,
                        coplanar: false,
                    }),
                    Err(_) => Err(first),
                }
            }
            Err(e) => Err(e),
        }
    }

    /// Refine a caller-supplied pose (e.g. a tracker's prediction) by LM, skipping the
    /// initialisation. Works for coplanar and non-coplanar points alike; it converges to the
    /// minimum nearest the initial pose.
    pub fn refine(
        &self,
        model: &[Point3<f64>],
        image: &[Point2<f64>],
        initial: &Pose,
    ) -> Result<Estimate, PoseError> {
        self.validate(model, image)?;
        if !initial.is_finite() {
            return Err(PoseError::NonFinite {
                which: "initial pose",
                index: 0,
            });
        }
        let pixels = self.undistort(image)?;
        self.refine_checked(model, pixels.as_slice(), initial)
    }

    /// Both refined pose candidates of coplanar model points (one marker face), best first, so
    /// a caller can pick the one consistent with a prediction. Points that are not coplanar
    /// (within `planarity_tolerance`) are a [`PoseError::Degenerate`] error.
    pub fn planar_candidates(
        &self,
        model: &[Point3<f64>],
        image: &[Point2<f64>],
    ) -> Result<[Estimate; 2], PoseError> {
        let geo = self.validate(model, image)?;
        if !geo.coplanar {
            return Err(PoseError::Degenerate {
                reason: "planar_candidates needs coplanar model points",
            });
        }
        let pixels = self.undistort(image)?;
        self.planar_refined(model, pixels.as_slice(), &geo)
    }

    /// Refines the pose of a body constrained to a plane (see [`crate::plane`]): model points
    /// in the body frame, their pixels, the plane's frame in the camera frame and a start
    /// (e.g. [`PlaneFrame::planar_from_pose`] of a 6-DOF solution). It converges to the
    /// minimum nearest `initial`; running out of iterations is not an error but an estimate
    /// with `converged: false`.
    ///
    /// # Errors
    /// Bad input as for [`PoseSolver::refine`] (too few points, mismatched lengths,
    /// non-finite numbers, including the plane and the start), a point behind the camera at
    /// the start, and a Jacobian that does not fix the three parameters at the optimum.
    pub fn refine_on_plane(
        &self,
        plane: &PlaneFrame,
        model: &[Point3<f64>],
        image: &[Point2<f64>],
        initial: &PlanarPose,
    ) -> Result<PlanarEstimate, PoseError> {
        check_inputs(model, image, &self.options)?;
        if !plane.is_finite() {
            return Err(PoseError::NonFinite {
                which: "plane frame",
                index: 0,
            });
        }
        if !initial.is_finite() {
            return Err(PoseError::NonFinite {
                which: "initial pose",
                index: 0,
            });
        }
        let pixels = self.undistort(image)?;
        let problem = PlaneReprojection {
            k: &self.intrinsics,
            plane,
            model,
            image: pixels.as_slice(),
        };
        let (r, converged) = match lm::refine(&problem, initial, &self.options.plane_lm)? {
            Ok(r) => (r, true),
            Err(u) => (u, false),
        };
        let n = model.len();
        Ok(PlanarEstimate {
            pose: r.pose,
            rms: (r.normal.sse / n as f64).sqrt(),
            covariance: lm::covariance(&r.normal, n, self.options.min_pixel_sigma)?,
            iterations: r.iterations,
            converged,
        })
    }

    /// With a lens model set, refines each candidate (from the solve on undistorted pixels)
    /// once more with the residual in the detected, distorted pixels `image`, and reorders
    /// them (see `lm::DistortedReprojection`); the RMS and covariance are then those of the
    /// detected pixels. A candidate whose refinement fails keeps its first estimate. Without
    /// a lens model the candidates are returned as they are.
    pub(crate) fn refine_in_detected_pixels(
        &self,
        model: &[Point3<f64>],
        image: &[Point2<f64>],
        candidates: [Estimate; 2],
    ) -> [Estimate; 2] {
        let Some(d) = &self.distortion else {
            return candidates;
        };
        let problem = lm::DistortedReprojection {
            k: &self.intrinsics,
            distortion: d,
            model,
            image,
        };
        let [a, b] = candidates.map(|c| {
            let refined = match lm::refine(&problem, &c.pose, &self.options.lm) {
                Ok(Ok(r)) => self.estimate(r.pose, &r.normal, r.iterations, true, model.len()),
                Ok(Err(u)) => self.estimate(u.pose, &u.normal, u.iterations, false, model.len()),
                Err(e) => Err(e),
            };
            match refined {
                Ok(e) if e.converged || !c.converged => e,
                _ => c,
            }
        });
        if rank(&b) < rank(&a) { [b, a] } else { [a, b] }
    }

    /// LM from `initial`; a non-converged solve is an error carrying its estimate.
    fn refine_checked(
        &self,
        model: &[Point3<f64>],
        px: &[Point2<f64>],
        initial: &Pose,
    ) -> Result<Estimate, PoseError> {
        let problem = lm::Reprojection {
            k: &self.intrinsics,
            model,
            image: px,
        };
        match lm::refine(&problem, initial, &self.options.lm)? {
            Ok(r) => self.estimate(r.pose, &r.normal, r.iterations, true, model.len()),
            Err(u) => Err(PoseError::NotConverged {
                iterations: u.iterations,
                estimate: u.pose,
            }),
        }
    }

    fn estimate(
        &self,
        pose: Pose,
        normal: &Normal<6>,
        iterations: usize,
        converged: bool,
        n: usize,
    ) -> Result<Estimate, PoseError> {
        let covariance = lm::covariance(normal, n, self.options.min_pixel_sigma)?;
        Ok(Estimate {
            pose,
            rms: (normal.sse / n as f64).sqrt(),
            covariance,
            iterations,
            converged,
        })
    }

    /// IPPE candidates of the best-fit plane, each refined on the full model; best first.
    ///
    /// The homography of four noisy points on a face seen nearly edge-on can imply a plane
    /// that passes behind the camera; when neither candidate of the projective homography can
    /// be refined, the candidates of its affine (weak-perspective) approximation are tried.
    fn planar_refined(
        &self,
        model: &[Point3<f64>],
        px: &[Point2<f64>],
        geo: &Geometry,
    ) -> Result<[Estimate; 2], PoseError> {
        let k = &self.intrinsics;
        let f = &geo.frame;
        let plane = |i: usize| {
            let d = model[i].coords - geo.centroid;
            Point2::new(f.column(0).dot(&d), f.column(1).dot(&d))
        };
        let normalized = |i: usize| (plane(i), k.pixel_to_normalized(&px[i]));
        let projective = ippe::homography(model.len(), normalized)
            .and_then(|h| self.refine_candidates(model, px, geo, &h, plane));
        match projective {
            Ok(c) => Ok(c),
            Err(e @ PoseError::NotConverged { .. }) => Err(e),
            Err(first) => {
                let h = ippe::affine_homography(model.len(), normalized)?;
                self.refine_candidates(model, px, geo, &h, plane)
                    .map_err(|_| first)
            }
        }
    }

    /// Both IPPE rotations of `h` (plane to normalised image), their translations, LM.
    fn refine_candidates(
        &self,
        model: &[Point3<f64>],
        px: &[Point2<f64>],
        geo: &Geometry,
        h: &Matrix3<f64>,
        plane: impl Fn(usize) -> Point2<f64>,
    ) -> Result<[Estimate; 2], PoseError> {
        let k = &self.intrinsics;
        let f = &geo.frame;
        let (r1, r2) = ippe::rotations(h)?;
        let mut out: [Option<Estimate>; 2] = [None, None];
        let mut first_err = None;
        for (slot, r) in out.iter_mut().zip([r1, r2]) {
            let t = ippe::translation(&r, model.len(), |i| {
                (plane(i), k.pixel_to_normalized(&px[i]))
            })?;
            // Camera-from-rig: R_rig = R F^T, t_rig = t - R_rig c.
            let r_rig = r * f.transpose();
            let init = Pose::from_matrix(&r_rig, t - r_rig * geo.centroid);
            let problem = lm::Reprojection {
                k,
                model,
                image: px,
            };
            let res = match lm::refine(&problem, &init, &self.options.lm) {
                Ok(Ok(r)) => self.estimate(r.pose, &r.normal, r.iterations, true, model.len()),
                Ok(Err(u)) => self.estimate(u.pose, &u.normal, u.iterations, false, model.len()),
                Err(e) => Err(e),
            };
            match res {
                Ok(e) => *slot = Some(e),
                Err(e) => first_err = first_err.or(Some(e)),
            }
        }
        let (a, b) = match out {
            [Some(a), Some(b)] => (a, b),
            // One candidate failed (e.g. behind the camera): report the other twice, so the
            // caller sees no ambiguity.
            [Some(a), None] | [None, Some(a)] => (a, a),
            [None, None] => {
                return Err(first_err.unwrap_or(PoseError::Degenerate {
                    reason: "no IPPE candidate",
                }));
            }
        };
        let (best, other) = if rank(&b) < rank(&a) { (b, a) } else { (a, b) };
        if !best.converged {
            return Err(PoseError::NotConverged {
                iterations: best.iterations,
                estimate: best.pose,
            });
        }
        Ok([best, other])
    }

    fn undistort<'a>(&self, image: &'a [Point2<f64>]) -> Result<Pixels<'a>, PoseError> {
        let Some(d) = &self.distortion else {
            return Ok(Pixels::Borrowed(image));
        };
        let k = &self.intrinsics;
        // Name the offending point in the error.
        let one = |i: usize, m: &Point2<f64>| {
            d.undistort_pixel(k, m).map_err(|e| match e {
                PoseError::NonFinite { which, .. } => PoseError::NonFinite { which, index: i },
                other => other,
            })
        };
        if image.len() <= STACK_POINTS {
            let mut buf = [Point2::origin(); STACK_POINTS];
            for (i, (slot, m)) in buf.iter_mut().zip(image).enumerate() {
                *slot = one(i, m)?;
            }
            Ok(Pixels::Stack(buf, image.len()))
        } else {
            image
                .iter()
                .enumerate()
                .map(|(i, m)| one(i, m))
                .collect::<Result<Vec<_>, _>>()
                .map(Pixels::Heap)
        }
    }

    /// Input checks shared by every entry point.
    fn validate(
        &self,
        model: &[Point3<f64>],
        image: &[Point2<f64>],
    ) -> Result<Geometry, PoseError> {
        validate(model, image, &self.options)
    }
}

/// Converged candidates first, then lower RMS.
fn rank(e: &Estimate) -> (bool, f64) {
    (!e.converged, e.rms)
}

fn check_options(opts: &SolverOptions) -> Result<(), PoseError> {
    let (lm, plm) = (&opts.lm, &opts.plane_lm);
    for (name, value) in [
        ("min_pixel_sigma", opts.min_pixel_sigma),
        ("planarity_tolerance", opts.planarity_tolerance),
        ("collinearity_tolerance", opts.collinearity_tolerance),
        ("lm.gradient_tolerance", lm.gradient_tolerance),
        ("lm.step_tolerance", lm.step_tolerance),
        ("lm.relative_cost_tolerance", lm.relative_cost_tolerance),
        ("lm.initial_damping", lm.initial_damping),
        ("plane_lm.gradient_tolerance", plm.gradient_tolerance),
        ("plane_lm.step_tolerance", plm.step_tolerance),
        (
            "plane_lm.relative_cost_tolerance",
            plm.relative_cost_tolerance,
        ),
        ("plane_lm.initial_damping", plm.initial_damping),
    ] {
        if !value.is_finite() || value < 0.0 {
            return Err(PoseError::InvalidOptions { name, value });
        }
    }
    Ok(())
}

/// Options, lengths and finiteness of the inputs.
fn check_inputs(
    model: &[Point3<f64>],
    image: &[Point2<f64>],
    opts: &SolverOptions,
) -> Result<(), PoseError> {
    check_options(opts)?;
    posit::check_correspondences(model, image)?;
    if let Some(index) = model
        .iter()
        .position(|p| !p.coords.iter().all(|v| v.is_finite()))
    {
        return Err(PoseError::NonFinite {
            which: "model",
            index,
        });
    }
    if let Some(index) = image
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(PoseError::NonFinite {
            which: "image",
            index,
        });
    }
    Ok(())
}

/// [`check_inputs`], then the shape of the model: no coincident points, not collinear,
/// coplanar or not.
fn validate(
    model: &[Point3<f64>],
    image: &[Point2<f64>],
    opts: &SolverOptions,
) -> Result<Geometry, PoseError> {
    check_inputs(model, image, opts)?;
    let n = model.len() as f64;
    let centroid = model.iter().fold(Vector3::zeros(), |acc, p| acc + p.coords) / n;
    let mut scatter = Matrix3::<f64>::zeros();
    let mut spread2 = 0.0f64;
    for p in model {
        let d = p.coords - centroid;
        scatter += d * d.transpose();
        spread2 = spread2.max(d.norm_squared());
    }
    let tol2 = (1e-9f64).powi(2) * spread2;
    for i in 0..model.len() {
        for j in i + 1..model.len() {
            if (model[i] - model[j]).norm_squared() <= tol2 {
                return Err(PoseError::CoincidentPoints {
                    first: i,
                    second: j,
                });
            }
        }
    }
    let eig = SymmetricEigen::new(scatter);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let l = order.map(|i| eig.eigenvalues[i].max(0.0));
    let line_ratio = (l[1] / l[0]).sqrt();
    if line_ratio.is_nan() || line_ratio < opts.collinearity_tolerance {
        return Err(PoseError::CollinearPoints { ratio: line_ratio });
    }
    // RMS off-plane distance over RMS in-plane spread.
    let plane_ratio = (l[2] / (l[0] + l[1])).sqrt();
    let e1 = eig.eigenvectors.column(order[0]).into_owned();
    let e2 = eig.eigenvectors.column(order[1]).into_owned();
    let frame = Matrix3::from_columns(&[e1, e2, e1.cross(&e2)]);
    Ok(Geometry {
        coplanar: plane_ratio < opts.planarity_tolerance,
        centroid,
        frame,
    })
}
