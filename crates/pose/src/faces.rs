//! The pose of a rigid body seen through several planar faces (a marker rig), with a face
//! that disagrees with the others found and dropped.
//!
//! # Why a joint pose, and how a bad face is found
//! One face is a plane, and a plane seen from afar has two pose minima that trade places
//! under noise (spec 4.4). Two or more octagon faces are not coplanar, so solving them
//! together (POSIT, then Levenberg-Marquardt on all corners, [`PoseSolver::solve`]) has a single minimum
//! and uses every corner. The price is that one wrong marker (a code misread as this robot's,
//! or a corner caught on a neighbouring edge) pulls the whole pose. So after the joint solve
//! each face's own reprojection RMS is checked: when one face is far above the others
//! (more than [`FaceCheck::outlier_px`] and [`FaceCheck::outlier_factor`] times the
//! median of the rest), the pose is solved leave-one-out and the face whose removal leaves
//! the best fit is dropped; this repeats while a face stands out and at least two faces
//! remain. With exactly two faces there is no majority, so the rig's geometry decides: the
//! faces' relative poses are known, so each face solved alone predicts where the other
//! face's corners must be. A face cut by an occluder (a side running along the occluder's
//! edge, a corner cut off) gives a wrong pose that misplaces every corner of the good face,
//! while the good face's pose still places at least two corners of the cut face (those the
//! occluder left alone) where they were read. The face whose pose explains the other face
//! better is kept (by its second-best corner, so two agreeing corners suffice); only when
//! neither single-face pose can be solved is the smaller face dropped. Every face dropped
//! is reported with the reason ([`Consistent::rejected`]).
//!
//! A small cut (a few percent of a face's width) hides under the 6-DOF joint pose, which
//! tilts to absorb it. With [`FaceCheck::plane_face_check`] (off by default in
//! `formation-tracker`: it also drops good steep faces), on the ground plane the pose has three degrees of
//! freedom for eight corners a face, so a cut face leaves a residual there: when a corner
//! lies more than [`FaceCheck::corner_outlier_px`] from the joint planar fit, each face is
//! left out in turn, the others are fitted on the plane, and the face that lets the others
//! fit within that limit *and* keeps at least two of its own corners there (an occluder
//! moves one side, not the whole face) while another of its corners is more than twice the
//! limit and five times that misfit away is dropped. In the occluder property test (noise-free corners, cuts of 6-40 %
//! of a face's width; runs of 3,000 and 10,000 cases), the cut faces this stage dropped had
//! a corner 0.45 px or more from the other faces' pose, the others fitting within 0.1 px.
//!

use nalgebra::{Point2, Point3};

use unicycle::PlanarPose;

use crate::{PlanarEstimate, PlaneFrame, PoseError, PoseSolution, PoseSolver};

/// One face of the body as read in an image: its number, its four corners in the body frame
/// and where they were read (pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Face {
    /// The face's number, for the rejection reasons.
    pub face: u8,
    /// The corners in the body frame, metres.
    pub model: [Point3<f64>; 4],
    /// The corners as read, pixels, in the same order.
    pub image: [Point2<f64>; 4],
}

/// A face that was read but not used for the pose, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Rejection {
    /// Face number.
    pub face: u8,
    /// Why it was dropped, with the figures that decided (pixels).
    pub reason: String,
}

/// The thresholds of [`consistent_faces`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceCheck {
    /// Faces are checked for consistency only when one face's reprojection RMS under the
    /// joint pose exceeds this (pixels); leaving a face out must bring the RMS below half of
    /// it, or divide it by `outlier_factor`.
    pub outlier_px: f64,
    /// See `outlier_px`.
    pub outlier_factor: f64,
    /// On the ground plane: when a corner lies farther than this (pixels) from where the
    /// joint planar pose puts it, the faces are checked for one that the body's geometry
    /// cannot explain (see the module documentation).
    pub corner_outlier_px: f64,
    /// Whether the ground-plane check of `corner_outlier_px` runs.
    pub plane_face_check: bool,
}

/// The area of a quadrilateral (shoelace formula), square pixels.
pub fn quad_area(c: &[Point2<f64>; 4]) -> f64 {
    let mut a = 0.0;
    for i in 0..4 {
        let (p, q) = (c[i], c[(i + 1) % 4]);
        a += p.x * q.y - q.x * p.y;
    }
    (a / 2.0).abs()
}

/// Joint solve of `faces`; per-face RMS under the result.
fn joint(solver: &PoseSolver, faces: &[Face]) -> Result<(PoseSolution, Vec<f64>), PoseError> {
    let model: Vec<Point3<f64>> = faces.iter().flat_map(|f| f.model).collect();
    let image: Vec<Point2<f64>> = faces.iter().flat_map(|f| f.image).collect();
    let sol = solver.solve(&model, &image)?;
    let p = sol.pose();
    let k = solver.intrinsics();
    let per_face = faces
        .iter()
        .map(|f| {
            let mut s = 0.0;
            for (m, i) in f.model.iter().zip(&f.image) {
                s += match k.project(&p.transform_point(m)) {
                    Ok(q) => (q - i).norm_squared(),
                    Err(_) => f64::INFINITY,
                };
            }
            (s / 4.0).sqrt()
        })
        .collect();
    Ok((sol, per_face))
}

/// The faces of a body that agree with each other, the joint pose of those faces and the
/// faces rejected (see the module documentation).
#[derive(Debug, Clone)]
pub struct Consistent {
    /// The faces kept.
    pub faces: Vec<Face>,
    /// The faces dropped, each with its reason.
    pub rejected: Vec<Rejection>,
    /// The joint pose of the faces kept.
    pub solution: PoseSolution,
}

/// Solves `faces` jointly and drops faces that disagree with the others while one stands
/// out and at least two remain; with `plane` (the plane the body stands on, in the camera
/// frame), the ground-plane check of [`FaceCheck::plane_face_check`] follows.
///
/// # Errors
/// The joint solve failing ([`PoseSolver::solve`]).
pub fn consistent_faces(
    mut faces: Vec<Face>,
    solver: &PoseSolver,
    plane: Option<&PlaneFrame>,
    config: &FaceCheck,
) -> Result<Consistent, PoseError> {
    let mut rejected = Vec::new();
    let (mut sol, mut per_face) = joint(solver, &faces)?;
    while faces.len() >= 2 && per_face.iter().any(|&r| r > config.outlier_px) {
        let worst = per_face.iter().copied().fold(0.0, f64::max);
        let (drop, reason) = if faces.len() == 2 {
            two_faces(solver, &faces, worst)
        } else {
            match face_to_leave_out(&faces, solver, &sol, config) {
                Some((i, rest_rms)) => (
                    i,
                    format!(
                        "inconsistent with the other faces of the rig: {:.2} px reprojection \
                         under the joint pose of all faces, {rest_rms:.2} px without it",
                        per_face[i]
                    ),
                ),
                None => break,
            }
        };
        let face = faces.remove(drop).face;
        rejected.push(Rejection { face, reason });
        (sol, per_face) = joint(solver, &faces)?;
    }
    if let Some(plane) = plane.filter(|_| faces.len() >= 2) {
        let before = rejected.len();
        plane_outliers(&mut faces, &mut rejected, solver, plane, config);
        if rejected.len() > before {
            sol = joint(solver, &faces)?.0;
        }
    }
    Ok(Consistent {
        faces,
        rejected,
        solution: sol,
    })
}

/// How far each corner of `face` lies from its projection under the planar pose `q` of the
/// rig on `plane` (pixels; infinite for a corner behind the camera).
fn plane_corner_errors(
    solver: &PoseSolver,
    plane: &PlaneFrame,
    face: &Face,
    q: &PlanarPose,
) -> [f64; 4] {
    let (r, t) = plane.body_to_camera(q);
    let k = solver.intrinsics();
    let mut d = [f64::INFINITY; 4];
    for (di, (m, i)) in d.iter_mut().zip(face.model.iter().zip(&face.image)) {
        if let Ok(p) = k.project(&Point3::from(r * m.coords + t)) {
            *di = (p - i).norm();
        }
    }
    d
}

/// The best fit of `faces` on the ground plane, seeded by every candidate of their 6-DOF
/// solve and by `seed`.
fn plane_fit(
    solver: &PoseSolver,
    plane: &PlaneFrame,
    faces: &[&Face],
    seed: Option<PlanarPose>,
) -> Option<PlanarEstimate> {
    let model: Vec<Point3<f64>> = faces.iter().flat_map(|f| f.model).collect();
    let image: Vec<Point2<f64>> = faces.iter().flat_map(|f| f.image).collect();
    let mut seeds: Vec<PlanarPose> = seed.into_iter().collect();
    if let Ok(sol) = solver.solve(&model, &image) {
        seeds.extend(
            std::iter::once(sol.best)
                .chain(sol.alternative)
                .map(|e| plane.planar_from_pose(&e.pose)),
        );
    }
    seeds
        .iter()
        .filter_map(|q0| solver.refine_on_plane(plane, &model, &image, q0).ok())
        .filter(|f| f.rms.is_finite() && f.pose.is_finite())
        .min_by(|a, b| a.rms.total_cmp(&b.rms))
}

/// The ground-plane check (see the module documentation): while two faces or more remain
/// and a corner lies more than [`FaceCheck::corner_outlier_px`] from the joint planar
/// fit, each face is left out in turn; the face whose removal leaves the others fitting and
/// at least two of its own corners where their pose puts them is dropped, if it is clearly
/// off (a corner beyond the limit) while the rest agree within it.
fn plane_outliers(
    faces: &mut Vec<Face>,
    rejected: &mut Vec<Rejection>,
    solver: &PoseSolver,
    plane: &PlaneFrame,
    config: &FaceCheck,
) {
    while faces.len() >= 2 {
        let all: Vec<&Face> = faces.iter().collect();
        let Some(fit) = plane_fit(solver, plane, &all, None) else {
            return;
        };
        let worst = faces
            .iter()
            .flat_map(|f| plane_corner_errors(solver, plane, f, &fit.pose))
            .fold(0.0, f64::max);
        if !config.plane_face_check || worst.is_nan() || worst <= config.corner_outlier_px {
            return;
        }
        // (face, score, the rest's RMS, its farthest corner under the rest's pose)
        let mut best: Option<(usize, f64, f64, f64)> = None;
        for i in 0..faces.len() {
            let rest: Vec<&Face> = faces
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, f)| f)
                .collect();
            let Some(r) = plane_fit(solver, plane, &rest, Some(fit.pose)) else {
                continue;
            };
            let mut e = plane_corner_errors(solver, plane, &faces[i], &r.pose);
            e.sort_by(f64::total_cmp);
            // A face cut by an occluder keeps at least two corners where the rig puts them.
            let score = r.rms.max(e[1]);
            if best.is_none_or(|b| score < b.1) {
                best = Some((i, score, r.rms, e[3]));
            }
        }
        let Some((i, score, rest_rms, off)) = best else {
            return;
        };
        // Clearly off: beyond twice the limit and five times the misfit of what agrees (a
        // steep face's corner 0.5 px off among faces fitting to 0.13 px is noise, not a cut).
        if !(score <= config.corner_outlier_px
            && off > (2.0 * config.corner_outlier_px).max(5.0 * score))
        {
            return;
        }
        let face = faces.remove(i).face;
        rejected.push(Rejection {
            face,
            reason: format!(
                "inconsistent with the rig on the ground plane: a corner {worst:.2} px off \
                 under the joint pose of all faces; the other faces alone fit to \
                 {rest_rms:.2} px and put a corner of this face {off:.2} px from where it \
                 was read"
            ),
        });
    }
}

/// How far the pose of `from` alone (its better planar candidate) places the corners of
/// `other` from where they were read: the second smallest of the four distances (pixels),
/// so that two corners in place suffice. `None` when `from` alone cannot be solved.
fn misplacement(solver: &PoseSolver, from: &Face, other: &Face) -> Option<f64> {
    let sol = solver.solve(&from.model, &from.image).ok()?;
    let k = solver.intrinsics();
    std::iter::once(sol.best)
        .chain(sol.alternative)
        .filter_map(|e| {
            let mut d = [0.0; 4];
            for (di, (m, i)) in d.iter_mut().zip(other.model.iter().zip(&other.image)) {
                *di = (k.project(&e.pose.transform_point(m)).ok()? - i).norm();
            }
            d.sort_by(f64::total_cmp);
            d[1].is_finite().then_some(d[1])
        })
        .reduce(f64::min)
}

/// Of two faces that disagree (`worst`: the larger per-face RMS under their joint pose), the
/// one to drop and why: the face whose own pose explains the other face worse (see the
/// module documentation); the smaller quad when neither can be solved alone.
fn two_faces(solver: &PoseSolver, faces: &[Face], worst: f64) -> (usize, String) {
    let (a, b) = (&faces[0], &faces[1]);
    match (misplacement(solver, a, b), misplacement(solver, b, a)) {
        (Some(ab), Some(ba)) => {
            // Drop the face whose pose misplaces the other more.
            let (drop, keep, by_drop, by_keep) = if ba > ab {
                (1, a.face, ba, ab)
            } else {
                (0, b.face, ab, ba)
            };
            (
                drop,
                format!(
                    "inconsistent with face {keep} of the rig ({worst:.2} px reprojection under \
                     their joint pose): its own pose misplaces face {keep} by {by_drop:.2} px, \
                     face {keep}'s pose misplaces it by {by_keep:.2} px"
                ),
            )
        }
        _ => {
            let drop = usize::from(quad_area(&a.image) >= quad_area(&b.image));
            (
                drop,
                format!(
                    "inconsistent with face {} of the rig ({worst:.2} px reprojection under \
                     their joint pose) and the smaller of the two in the image",
                    faces[1 - drop].face
                ),
            )
        }
    }
}

/// Leave one out: the face whose removal fits the rest best, with the RMS of the rest, if
/// that is a clear improvement on the joint pose `sol`.
fn face_to_leave_out(
    faces: &[Face],
    solver: &PoseSolver,
    sol: &PoseSolution,
    config: &FaceCheck,
) -> Option<(usize, f64)> {
    let mut best: Option<(usize, f64)> = None;
    for i in 0..faces.len() {
        let rest: Vec<Face> = faces
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, f)| *f)
            .collect();
        if let Ok((s, _)) = joint(solver, &rest)
            && best.is_none_or(|(_, r)| s.rms() < r)
        {
            best = Some((i, s.rms()));
        }
    }
    match best {
        Some((i, r)) if r < sol.rms() / config.outlier_factor || r <= config.outlier_px / 2.0 => {
            Some((i, r))
        }
        _ => None,
    }
}

/// The best fit of `faces` on `plane` (the plane the body stands on, in the camera frame),
/// seeded by every candidate of their 6-DOF solve `sol`, with the heading wrapped to
/// `(-pi, pi]`; and, when the faces are coplanar (a single face), the ambiguity: the RMS of
/// the other distinct fit over the best's.
///
/// # Errors
/// [`PoseError::Degenerate`] when no refinement converges.
pub fn fit_on_plane(
    faces: &[Face],
    sol: &PoseSolution,
    solver: &PoseSolver,
    plane: &PlaneFrame,
) -> Result<(PlanarEstimate, Option<f64>), PoseError> {
    let model: Vec<Point3<f64>> = faces.iter().flat_map(|f| f.model).collect();
    let image: Vec<Point2<f64>> = faces.iter().flat_map(|f| f.image).collect();
    let seeds = std::iter::once(&sol.best)
        .chain(&sol.alternative)
        .map(|e| plane.planar_from_pose(&e.pose));
    let fits: Vec<PlanarEstimate> = seeds
        .filter_map(|q0| solver.refine_on_plane(plane, &model, &image, &q0).ok())
        .map(|mut fit| {
            fit.pose.theta = unicycle::wrap_angle(fit.pose.theta);
            fit
        })
        .collect();
    let best = fits
        .iter()
        .min_by(|a, b| a.rms.total_cmp(&b.rms))
        .copied()
        .ok_or(PoseError::Degenerate {
            reason: "the ground-plane refinement did not converge",
        })?;
    let q = best.pose.to_vector();
    let ambiguity_ratio = if sol.coplanar {
        fits.iter()
            .filter(|f| (f.pose.to_vector() - q).norm() > 1e-4)
            .map(|f| f.rms / best.rms.max(1e-12))
            .reduce(f64::min)
    } else {
        None
    };
    Ok((best, ambiguity_ratio))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Intrinsics, Pose};
    use nalgebra::{Rotation3, Vector3};

    /// Face `face` of a body: a 0.14 m square on a vertical plane `0.2` m from the body's
    /// axis, facing the horizontal direction `yaw_deg`, centred 0.3 m up.
    fn model(yaw_deg: f64) -> [Point3<f64>; 4] {
        let yaw = yaw_deg.to_radians();
        let (n, t) = (
            Vector3::new(yaw.cos(), yaw.sin(), 0.0),
            Vector3::new(-yaw.sin(), yaw.cos(), 0.0),
        );
        let c = n * 0.2 + Vector3::z() * 0.3;
        let (h, up) = (0.07, Vector3::z() * 0.07);
        [
            c - t * h + up,
            c + t * h + up,
            c + t * h - up,
            c - t * h - up,
        ]
        .map(Point3::from)
    }

    /// The body 1.5 m ahead of a level camera, facing away from it, turned by `turn`.
    fn pose(turn: f64) -> Pose {
        // Body x (forward) -> camera z, body y (left) -> camera -x, body z (up) -> camera -y.
        let to_camera = Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            0.0, -1.0, 0.0, //
            0.0, 0.0, -1.0, //
            1.0, 0.0, 0.0,
        )) * Rotation3::from_axis_angle(&Vector3::z_axis(), turn);
        Pose::new(to_camera.scaled_axis(), Vector3::new(0.05, 0.25, 1.5))
    }

    fn faces(k: &Intrinsics, p: &Pose) -> Vec<Face> {
        [(2u8, 135.0), (3, 180.0), (4, -135.0)]
            .iter()
            .map(|&(face, yaw)| {
                let model = model(yaw);
                let image = model.map(|m| k.project(&p.transform_point(&m)).unwrap());
                Face { face, model, image }
            })
            .collect()
    }

    fn check() -> FaceCheck {
        FaceCheck {
            outlier_px: 1.5,
            outlier_factor: 3.0,
            corner_outlier_px: 0.6,
            plane_face_check: false,
        }
    }

    #[test]
    fn the_area_of_a_quadrilateral_is_its_shoelace_area_either_way_round() {
        let square = [[0.0, 0.0], [2.0, 0.0], [2.0, 3.0], [0.0, 3.0]].map(Point2::from);
        assert!((quad_area(&square) - 6.0).abs() < 1e-15);
        let mut reversed = square;
        reversed.reverse();
        assert!((quad_area(&reversed) - 6.0).abs() < 1e-15);
    }

    #[test]
    fn agreeing_faces_are_kept_and_give_the_pose() {
        let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480).unwrap();
        let solver = PoseSolver::new(k);
        let truth = pose(0.3);
        let got = consistent_faces(faces(&k, &truth), &solver, None, &check()).unwrap();
        assert_eq!(got.faces.len(), 3);
        assert!(got.rejected.is_empty());
        let p = got.solution.pose();
        assert!((p.translation - truth.translation).norm() < 1e-6, "{p:?}");
        assert!((p.rotation - truth.rotation).norm() < 1e-6, "{p:?}");
    }

    #[test]
    fn a_face_that_disagrees_is_dropped_with_its_reason() {
        let k = Intrinsics::from_hfov(60f64.to_radians(), 640, 480).unwrap();
        let solver = PoseSolver::new(k);
        let truth = pose(0.3);
        let mut read = faces(&k, &truth);
        // Face 4 read 12 px to the right, as a misread marker or a wrong corner would be.
        for c in &mut read[2].image {
            c.x += 12.0;
        }
        let got = consistent_faces(read, &solver, None, &check()).unwrap();
        let kept: Vec<u8> = got.faces.iter().map(|f| f.face).collect();
        assert_eq!(kept, [2, 3]);
        assert_eq!(got.rejected.len(), 1);
        assert_eq!(got.rejected[0].face, 4);
        assert!(!got.rejected[0].reason.is_empty());
        let p = got.solution.pose();
        assert!((p.translation - truth.translation).norm() < 1e-6, "{p:?}");
    }
}
