//! After construction, a UKF step, a dual step and an IMM step perform zero heap allocations.
//!
//! A counting global allocator (per thread, so the test harness's own threads do not
//! interfere) counts every `alloc`/`realloc` made while the filters run.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use dukf::{AngleMask, DualUkf, Euclidean, Imm, Ukf, UtParams, sojourn_transition};
use nalgebra::{SMatrix, SVector};

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn bump() {
    // `try_with` so an allocation during thread teardown does not panic.
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: every method forwards to the system allocator unchanged; the counter is a
// const-initialised thread-local `Cell`, which never allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        bump();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        bump();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        bump();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

type V6 = SVector<f64, 6>;
type V3 = SVector<f64, 3>;
type V2 = SVector<f64, 2>;

const DT: f64 = 1.0 / 30.0;

/// A unicycle-like model with angles at 2, 4 and 5 (the shape of the formation tracker's).
fn f(x: &V6, w: &V2) -> V6 {
    let (v, om) = (w[0], w[1]);
    V6::from_column_slice(&[
        x[0] + DT * v * x[2].cos(),
        x[1] + DT * v * x[2].sin(),
        x[2] + DT * om,
        x[3] + DT * (v * x[4].cos() - 0.2 * x[5].cos()),
        x[4] + DT * (-v * x[4].sin() / x[3] - om),
        x[5] + DT * (-v * x[4].sin() / x[3] + 0.2 * x[5].sin() / x[3]),
    ])
}

fn h(x: &V6) -> V3 {
    V3::new(x[3], x[4], x[5])
}

#[test]
fn ukf_dual_and_imm_steps_do_not_allocate() {
    let x0 = V6::from_column_slice(&[1.5, 0.25, 0.0, 1.047, 0.233, 0.232]);
    let p0 = SMatrix::<f64, 6, 6>::identity() * 0.01;
    let q = SMatrix::<f64, 6, 6>::identity() * 1e-5;
    let r = SMatrix::<f64, 3, 3>::from_diagonal(&V3::new(0.07, 0.03, 0.03));
    let y = V3::new(1.05, 0.24, 0.22);
    let state_space = AngleMask::<6>::from_indices(&[2, 4, 5]).unwrap();
    let meas_space = AngleMask::<3>::from_indices(&[1, 2]).unwrap();

    let mut ukf = Ukf::new(x0, p0, state_space, UtParams::default()).unwrap();
    let w = V2::new(0.2, 0.1);
    // Also force the jitter repair path once: a rank-deficient prediction.
    let mut singular = Ukf::new(
        V2::zeros(),
        SMatrix::<f64, 2, 2>::identity(),
        Euclidean,
        UtParams::default(),
    )
    .unwrap();

    let params = Ukf::new(
        V2::zeros(),
        SMatrix::<f64, 2, 2>::identity(),
        Euclidean,
        UtParams::default(),
    )
    .unwrap();
    let state = Ukf::new(x0, p0, state_space, UtParams::default()).unwrap();
    let mut dual = DualUkf::new(
        state,
        params,
        q,
        SMatrix::<f64, 2, 2>::identity() * 1e-4,
        meas_space,
    )
    .unwrap();

    // A two-model IMM over the same state: model 0 with `w`, model 1 standing still.
    let member = Ukf::new(x0, p0, state_space, UtParams::default()).unwrap();
    let mut imm = Imm::new(
        [member, member],
        [0.5, 0.5],
        sojourn_transition::<2>(DT, 2.0).unwrap(),
    )
    .unwrap();
    let qs = [q, q];
    let still = V2::zeros();
    let fj = |j: usize, x: &V6| if j == 0 { f(x, &w) } else { f(x, &still) };

    let mut ok = true;
    let n = allocations_during(|| {
        for _ in 0..50 {
            ok &= ukf.predict(|x| f(x, &w), &q).is_ok();
            ok &= ukf.update(&y, h, &r, &meas_space).is_ok();
            ok &= dual.step(f, h, &y, &r).is_ok();
            ok &= dual.predict_only(f).is_ok();
            ok &= imm.step(fj, &qs, &y, h, &r, &meas_space).is_ok();
            ok &= imm.predict_only(fj, &qs).is_ok();
            ok &= imm.estimate().0.iter().all(|v| v.is_finite());
            ok &= singular
                .predict(|x| V2::new(x[0], x[0]), &SMatrix::<f64, 2, 2>::zeros())
                .is_ok_and(|rep| rep.jitter > 0.0);
        }
    });
    assert!(ok, "every step must succeed");
    assert_eq!(n, 0, "{n} heap allocations during filter steps");

    // The counter does count: an allocation is seen (so a zero above means something).
    let seen = allocations_during(|| {
        let v: Vec<u64> = std::hint::black_box(vec![1, 2, 3]);
        assert_eq!(v.len(), 3);
    });
    assert!(seen >= 1);
}
