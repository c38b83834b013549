//! A pure-Rust synthetic camera: ray-cast scenes of unicycle robots carrying marker rigs, with
//! exact ground truth.
//!
//! The paper checks its tracker against a synthetic OpenGL camera. This crate is our own: it
//! renders grey (or RGB) images of robots standing on a ground plane, each carrying a rig of
//! flat textured faces (e.g. fiducial markers), and for every frame it
//! reports what the image *should* contain, computed exactly rather than measured.
//!
//! # Conventions (spec 2.1)
//! - World and robot body frames: x forward, y left, z up; angles counter-clockwise.
//! - PosedCamera frame (OpenCV): x right, y down, z along the optical axis.
//! - Pixels: u right, v down, integer coordinates at pixel *centres*; the image covers
//!   `[-0.5, w - 0.5] x [-0.5, h - 0.5]`. Pixel `(u, v)` sees the ray `K^-1 [u, v, 1]^T`.
//!
//! # Why ray casting
//! A rasteriser needs clipping, a depth buffer and careful edge rules to put edges exactly
//! where the pinhole model says, and its anti-aliasing model is hard to state. A ray caster
//! *is* the pinhole model: each sample is the ray `K^-1 [u, v, 1]^T` intersected with the
//! scene (ray-plane for the ground, ray-rectangle for faces, slab test for box bodies,
//! ray-cylinder for round bodies), nearest hit wins. So the rendered geometry and the ground
//! truth come from the same equations, and skew, off-centre principal points or odd image
//! sizes need no special code. The scenes are small (a few robots, five faces each), so the
//! cost is a handful of dot products per sample.
//!
//! Per frame, [`render`] transforms every object into the camera frame once, so a sample
//! needs only the ray direction (an affine function of `(u, v)`) and a few dot products per
//! object; each object carries a conservative screen-space bounding box (its projected
//! corners), so a pixel only tests objects whose box it meets. Rows are rendered in parallel
//! with rayon; nothing allocates per pixel.
//!
//! # Anti-aliasing model
//! A pixel's value is the mean over its area `[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]` of the
//! scene radiance (a box filter), estimated with `n x n` stratified samples, one per cell of an
//! `n x n` grid of sub-cells ([`RenderSettings::supersampling`] is `n`; "4x supersampling"
//! is `n = 2`), shifted within their cells so that all `n^2` samples have distinct columns and
//! distinct rows (the canonical multi-jittered pattern). A plain grid of cell centres sees an
//! edge parallel to a pixel axis at only `n` offsets, so it places it up to `1 / (2 n)` px off
//! (0.06 px at `n = 8`: enough to tilt a near-frontal marker's pose by a degree); this pattern
//! sees it at `n^2` offsets, within `1 / (2 n^2)` px. Sampling is deterministic (no jitter),
//! so the same scene renders the same image. With a box filter, the darkness summed across a straight edge equals the covered
//! area, which locates the edge: the crate's tests recover face corners from rendered images
//! this way and find them where the exact projection puts them, to 0.05 px.
//!
//! After sampling: optional Gaussian blur (optics, sigma in pixels), then additive Gaussian
//! sensor noise (sigma in grey levels, seeded `ChaCha8Rng`, one stream per row so the result
//! does not depend on thread scheduling), then rounding and clamping to 8 bits. The light is a
//! gain times an optional linear gradient across the image ([`Gradient`]); optional diffuse
//! shading ([`Shading`]) darkens bodies and the ground by their orientation to a directional
//! light, but leaves rig faces unshaded by default, so markers stay crisp and uniform.
//!
//! # Ground truth
//! [`render`] returns a [`FrameTruth`] (also available without rendering, [`ground_truth`]):
//! - per robot, the rigid transform body frame -> camera frame ([`RobotTruth::body_to_camera`]);
//! - per face ([`FaceTruth`]): the four corners NW, NE, SE, SW (as seen from outside the face)
//!   by exact pinhole projection, the width in pixels (mean of the projected top and bottom
//!   edges), the off-axis angle (between the outward normal and the direction from the face
//!   centre to the camera, degrees), and whether it is *visible*: front-facing, all corners in
//!   front of the camera and inside the image, and no corner occluded by another object or
//!   the ground (tested by casting a ray to each corner, pulled [`CORNER_INSET`] towards the
//!   face centre so neighbouring faces sharing an edge do not count).
//!
//! # Textures
//! A face shows a [`Texture`]: grey albedo over face coordinates `(s, t)` in `[0, 1]^2`, `s`
//! right and `t` down as seen from outside. [`CellGrid`] has exact cell edges and is how a
//! fiducial marker (border, data cells, quiet zone) is supplied; [`ImageTexture`] stretches a
//! grey buffer (nearest or bilinear); [`Uniform`] and [`SoftChecker`] (a smooth, low-contrast
//! ground pattern with no marker-like edges) complete the set. The crate knows nothing about
//! marker codes, dictionaries, rig layouts or robot dynamics: callers build textures and faces
//! from their own types.
//!
//! # Vocabulary
//! The pinhole model is `pose`'s ([`pose::Intrinsics`]; a [`PosedCamera`] adds the image size and
//! its pose), robots stand at `unicycle`'s planar [`unicycle::PlanarPose`], and a camera mounted on a
//! robot is given by the rigid transform camera frame -> body frame ([`PosedCamera::on_robot`]).
//!
//! # Example
//! ```
//! use std::sync::Arc;
//! use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
//! use synthcam::*;
//! use unicycle::PlanarPose;
//!
//! // One face 0.2 m behind the leader's reference point, looking backwards.
//! let marker: Arc<dyn Texture> = Arc::new(CellGrid::from_bits(2, 2, &[true, false, false, true])?);
//! let face = FacePlacement {
//!     centre: Point3::new(-0.2, 0.0, 0.3),
//!     normal: -Vector3::x(),
//!     up: Vector3::z(),
//!     width: 0.18,
//!     height: 0.16,
//! };
//! let leader = Robot::new(PlanarPose::new(1.5, 0.2, 0.0), Body::Cylinder { radius: 0.15, height: 0.2, albedo: 0.3 })
//!     .with_face(Face::new(3, face, marker));
//! let mut scene = Scene::new(0.8);
//! scene.robots.push(leader);
//! scene.ground = Some(Ground { texture: Arc::new(SoftChecker::new(0.45, 0.6)?), tile: 1.0 });
//!
//! // A level camera 0.1 m ahead of the follower's reference point and 0.3 m up (camera z
//! // along body x, camera y along body -z).
//! let camera_to_body = Isometry3::from_parts(
//!     Translation3::new(0.1, 0.0, 0.3),
//!     UnitQuaternion::face_towards(&Vector3::x(), &-Vector3::z()),
//! );
//! let intrinsics = pose::Intrinsics::from_hfov(60f64.to_radians(), 160, 120).expect("valid");
//! let camera = PosedCamera::on_robot(intrinsics, 160, 120, &camera_to_body, &PlanarPose::new(0.0, 0.0, 0.0))?;
//! let out = render(&scene, &camera, &RenderSettings::default())?;
//! assert_eq!(out.frame.data.len(), 160 * 120);
//! // The leader faces away from the camera, so its backward face (label 3) is visible.
//! assert!(out.truth.face(0, 3).is_some_and(|f| f.visible));
//! # Ok::<(), synthcam::SynthError>(())
//! ```
#![deny(missing_docs)]

/// This crate's version (`CARGO_PKG_VERSION`), for tools that report what they were built from.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

mod camera;
mod error;
mod raycast;
mod render;
mod scene;
mod texture;
mod truth;

pub use camera::{MAX_PIXELS, PosedCamera};
pub use error::{MAX_INTRINSIC, MAX_MAGNITUDE, SynthError};
pub use render::{
    Frame, Gradient, MAX_SUPERSAMPLING, PixelFormat, RenderSettings, Rendered, Shading, render,
    render_exposure, render_with_progress,
};
pub use scene::{Body, Face, FaceFrame, FacePlacement, Ground, Panel, Robot, Scene};
pub use texture::{CellGrid, Filter, ImageTexture, SoftChecker, Texture, Uniform};
pub use truth::{CORNER_INSET, FaceTruth, FrameTruth, RobotTruth, ground_truth};

/// The README's example, compiled and run as a doctest so it cannot rot.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;
