//! The solve paths for one face (4 points) and three faces (12 points), and the refinement on
//! a plane, do not touch the heap.
//! A counting global allocator sees every allocation of this test binary, which holds this one
//! test only.
#![allow(unsafe_code)] // implementing GlobalAlloc requires it; the impl only forwards to System.

mod common;

use common::*;
use nalgebra::Rotation3;
use pose::{Distortion, PlaneFrame, PoseSolver};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use unicycle::PlanarPose;

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn solves_do_not_allocate() {
    let k = camera();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let face = face_model();
    let face_px = project_all(&k, &random_face_pose(&mut rng, (0.5, 2.0), 1.0), &face);
    let rig = three_faces_model();
    let rig_pose = random_rig_pose(&mut rng);
    let rig_px = project_all(&k, &rig_pose, &rig);
    let d = Distortion::plumb_bob(-0.1, 0.02, 0.001, 0.0, 0.0).unwrap();
    let rig_px_distorted: Vec<_> = rig_px.iter().map(|m| d.distort_pixel(&k, m)).collect();
    // One 100 mm marker 0.8 m ahead, through the lens (OpenCV's marker frame).
    let marker_pose = pose::Pose::new(
        nalgebra::Vector3::new(3.0, 0.1, -0.2),
        nalgebra::Vector3::new(0.05, -0.03, 0.8),
    );
    let marker_px: [nalgebra::Point2<f64>; 4] = pose::marker_corners(0.1, 0.1)
        .unwrap()
        .map(|p| d.distort_pixel(&k, &k.project(&marker_pose.transform_point(&p)).unwrap()));
    let solver = PoseSolver::new(k);
    let with_lens = PoseSolver::new(k).with_distortion(d);
    // The rig standing at the origin of a plane whose frame is the rig's own.
    let plane = PlaneFrame {
        rotation: Rotation3::new(rig_pose.rotation),
        translation: rig_pose.translation,
    };
    let start = PlanarPose {
        x: 0.01,
        y: -0.01,
        theta: 0.02,
    };

    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let a = solver.solve(&face, &face_px);
    let b = solver.solve(&rig, &rig_px);
    let c = solver.refine(&rig, &rig_px, &rig_pose);
    let e = with_lens.solve(&rig, &rig_px_distorted);
    let f = solver.planar_candidates(&face, &face_px);
    let g = solver.refine_on_plane(&plane, &rig, &rig_px, &start);
    let h = with_lens.solve_square_marker(&marker_px, 0.1);
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(a.is_ok() && b.is_ok() && c.is_ok() && e.is_ok() && f.is_ok());
    assert!(h.is_ok(), "{h:?}");
    let g = g.expect("the rig on its plane");
    assert!(g.converged && g.pose.to_vector().norm() < 1e-9, "{g:?}");
    assert_eq!(
        after - before,
        0,
        "the solves allocated {} times",
        after - before
    );
}
