//! Criterion benchmarks of one UKF step and one dual step at the formation tracker's sizes.
//!
//! The model is a toy written here (the crate knows nothing about robots): a unicycle-like
//! polar model with 6 states, angles at indices 2, 4 and 5, 2 parameters and 3
//! measurements, one explicit Euler step of dt = 1/30 s per call.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use dukf::{AngleMask, DualUkf, Euclidean, Imm, Ukf, UtParams, sojourn_transition};
use nalgebra::{SMatrix, SVector};

type V6 = SVector<f64, 6>;
type V3 = SVector<f64, 3>;
type V2 = SVector<f64, 2>;

const DT: f64 = 1.0 / 30.0;
const D: f64 = 0.1;
const U: [f64; 2] = [0.2, 0.05];

fn f(x: &V6, w: &V2) -> V6 {
    let (v1, w1) = (w[0], w[1]);
    let (v2, w2) = (U[0], U[1]);
    let (sa, ca) = x[4].sin_cos();
    let (sb, cb) = x[5].sin_cos();
    let (st, ct) = x[2].sin_cos();
    let l = x[3];
    V6::from_column_slice(&[
        x[0] + DT * v1 * ct,
        x[1] + DT * v1 * st,
        x[2] + DT * w1,
        l + DT * (v1 * ca - v2 * cb - D * w2 * sb),
        x[4] + DT * ((-v1 * sa + v2 * sb - D * w2 * cb) / l - w1),
        x[5] + DT * ((-v1 * sa + v2 * sb) / l - w2 * (1.0 + D * cb / l)),
    ])
}

fn h(x: &V6) -> V3 {
    V3::new(x[3], x[4], x[5])
}

/// A measurement sequence from the model itself, cycled by the benchmarks.
fn measurements() -> Vec<V3> {
    let mut x = V6::from_column_slice(&[1.5, 0.25, 0.0, 1.047, 0.233, 0.232]);
    let w = V2::new(0.25, 0.1);
    (0..256)
        .map(|k| {
            x = f(&x, &w);
            let wobble = 0.01 * (f64::from(k) * 0.7).sin();
            V3::new(x[3] + wobble, x[4] - wobble, x[5] + wobble)
        })
        .collect()
}

fn spaces() -> (AngleMask<6>, AngleMask<3>) {
    (
        AngleMask::new([false, false, true, false, true, true]),
        AngleMask::new([false, true, true]),
    )
}

fn bench(c: &mut Criterion) {
    let ys = measurements();
    let (sx, sy) = spaces();
    let x0 = V6::from_column_slice(&[1.5, 0.25, 0.0, 1.047, 0.233, 0.232]);
    let p0 = SMatrix::<f64, 6, 6>::identity() * 0.01;
    let q = SMatrix::<f64, 6, 6>::identity() * 1e-5;
    let r = SMatrix::<f64, 3, 3>::from_diagonal(&V3::new(0.07, 0.03, 0.03));

    let w = V2::new(0.25, 0.1);
    let mut ukf = Ukf::new(x0, p0, sx, UtParams::default()).expect("valid filter");
    let mut k = 0;
    c.bench_function("dukf/ukf_step_6x3", |b| {
        b.iter(|| {
            let y = &ys[k % ys.len()];
            k += 1;
            ukf.predict(|x| f(x, &w), &q).expect("predict");
            black_box(ukf.update(black_box(y), h, &r, &sy).expect("update"))
        });
    });

    let state = Ukf::new(x0, p0, sx, UtParams::default()).expect("valid filter");
    let params = Ukf::new(
        V2::zeros(),
        SMatrix::<f64, 2, 2>::identity(),
        Euclidean,
        UtParams::default(),
    )
    .expect("valid filter");
    let mut dual = DualUkf::new(
        state,
        params,
        q,
        SMatrix::<f64, 2, 2>::identity() * 1e-4,
        sy,
    )
    .expect("valid dual filter");
    let mut k = 0;
    c.bench_function("dukf/dual_step_6_2x3", |b| {
        b.iter(|| {
            let y = &ys[k % ys.len()];
            k += 1;
            black_box(dual.step(f, h, black_box(y), &r).expect("dual step"))
        });
    });

    let mut k = 0;
    c.bench_function("dukf/dual_predict_only_6_2", |b| {
        b.iter(|| {
            k += 1;
            // Alternate with a step so the covariance does not grow without bound.
            if k % 2 == 0 {
                black_box(dual.predict_only(f).expect("predict only"));
            } else {
                black_box(dual.step(f, h, &ys[k % ys.len()], &r).expect("dual step"));
            }
        });
    });
}

/// One IMM step of two models over the same 6-state (model 0 moving with the toy's
/// velocities, model 1 standing still), as the formation filter runs it (at 10 states there).
fn bench_imm(c: &mut Criterion) {
    let ys = measurements();
    let (sx, sy) = spaces();
    let x0 = V6::from_column_slice(&[1.5, 0.25, 0.0, 1.047, 0.233, 0.232]);
    let p0 = SMatrix::<f64, 6, 6>::identity() * 0.01;
    let q = SMatrix::<f64, 6, 6>::identity() * 1e-5;
    let r = SMatrix::<f64, 3, 3>::from_diagonal(&V3::new(0.07, 0.03, 0.03));
    let member = Ukf::new(x0, p0, sx, UtParams::default()).expect("valid filter");
    let pi = sojourn_transition::<2>(DT, 2.0).expect("valid switching matrix");
    let mut imm = Imm::new([member, member], [0.5, 0.5], pi).expect("valid IMM");
    let (w, still) = (V2::new(0.25, 0.1), V2::zeros());
    let qs = [q, q];
    let mut k = 0;
    c.bench_function("dukf/imm_step_2x6x3", |b| {
        b.iter(|| {
            let y = &ys[k % ys.len()];
            k += 1;
            black_box(
                imm.step(
                    |j, x| if j == 0 { f(x, &w) } else { f(x, &still) },
                    &qs,
                    black_box(y),
                    h,
                    &r,
                    &sy,
                )
                .expect("imm step"),
            )
        });
    });
}

criterion_group!(benches, bench, bench_imm);
criterion_main!(benches);
