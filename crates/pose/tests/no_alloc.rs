//! The solve paths for one face (4 points) and three faces (12 points) do not touch the heap.
//! A counting global allocator sees every allocation of this test binary, which holds this one
//! test only.
#![allow(unsafe_code)] // implementing GlobalAlloc requires it; the impl only forwards to System.

mod common;

use common::*;
use pose::{Distortion, PoseSolver};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

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
    let d = Distortion::new(-0.1, 0.02, 0.001, 0.0, 0.0).unwrap();
    let rig_px_distorted: Vec<_> = rig_px.iter().map(|m| d.distort_pixel(&k, m)).collect();
    let solver = PoseSolver::new(k);
    let with_lens = PoseSolver::new(k).with_distortion(d);

    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let a = solver.solve(&face, &face_px);
    let b = solver.solve(&rig, &rig_px);
    let c = solver.refine(&rig, &rig_px, &rig_pose);
    let e = with_lens.solve(&rig, &rig_px_distorted);
    let f = solver.planar_candidates(&face, &face_px);
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(a.is_ok() && b.is_ok() && c.is_ok() && e.is_ok() && f.is_ok());
    assert_eq!(
        after - before,
        0,
        "the solves allocated {} times",
        after - before
    );
}
