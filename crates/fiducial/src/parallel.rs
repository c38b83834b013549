//! The threaded parts of [`Detector::detect_parallel`](crate::Detector::detect_parallel)
//! (issue #12) beyond banded binarization: the components of a frame are cut into as many
//! contiguous runs as there are threads, of about equal estimated work, and each run is
//! examined (traced, fitted, refined) on its own thread with its own scratch. The runs'
//! quads and re-cut boxes are then appended in order, so the result is exactly that of the
//! single-threaded loop. Decoding is cut the same way: contiguous runs of the quads, each
//! read on its own thread with its own scratch, the markers then merged in quad order as the
//! single-threaded loop merges them. Without the crate feature `parallel` the runs are
//! examined in turn.

use crate::contour::Component;
use crate::decode::Decoded;
use crate::detector::{DecodeContext, Decoding, Examined, Quad, Scan, push_unique};
use crate::image::GrayView;
use crate::refine::Refiner;
use crate::split::Rect;

/// One thread's scratch and results; kept by the detector between frames.
#[derive(Debug, Default, Clone)]
pub(crate) struct Worker {
    contour: Vec<[i32; 2]>,
    refiner: Refiner,
    quads: Vec<Quad>,
    retry: Vec<Rect>,
    /// The run of components (start, end) of the current frame.
    range: (usize, usize),
}

/// Estimated cost of examining a component: tracing and refinement grow with the outline,
/// up to the refiner's cap on edge profiles; components too small to examine cost little.
fn weight(c: &Component, min_side: u32) -> u64 {
    let (bw, bh) = (c.x_max - c.x_min + 1, c.y_max - c.y_min + 1);
    if bw.max(bh) < min_side {
        1
    } else {
        u64::from((bw + bh).min(512)) + 8
    }
}

/// Examines `components` on `threads` workers and appends their quads to `quads` and their
/// re-cut boxes to `retry`, in the order of the single-threaded loop.
pub(crate) fn examine_all(
    scan: &Scan<'_, '_>,
    components: &[Component],
    threads: usize,
    workers: &mut Vec<Worker>,
    quads: &mut Vec<Quad>,
    retry: &mut Vec<Rect>,
) {
    let k = threads.max(1);
    if workers.len() < k {
        workers.resize_with(k, Worker::default);
    }
    let workers = &mut workers[..k];
    // Contiguous runs of about equal total weight.
    let total: u64 = components.iter().map(|c| weight(c, scan.min_side)).sum();
    let (mut acc, mut j, mut begin) = (0u64, 0usize, 0usize);
    for (i, c) in components.iter().enumerate() {
        acc += weight(c, scan.min_side);
        while j + 1 < k && acc * k as u64 >= total * (j as u64 + 1) {
            workers[j].range = (begin, i + 1);
            begin = i + 1;
            j += 1;
        }
    }
    for w in &mut workers[j..] {
        w.range = (begin, components.len());
        begin = components.len();
    }
    let run = |w: &mut Worker| {
        w.quads.clear();
        w.retry.clear();
        for c in &components[w.range.0..w.range.1] {
            match scan.examine(c, &mut w.contour, &mut w.refiner) {
                Examined::Quad(q) => w.quads.push(q),
                Examined::Retry(r) => w.retry.push(r),
                Examined::Dropped => {}
            }
        }
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        workers.par_iter_mut().for_each(run);
    }
    #[cfg(not(feature = "parallel"))]
    workers.iter_mut().for_each(run);
    for w in workers.iter() {
        quads.extend_from_slice(&w.quads);
        retry.extend_from_slice(&w.retry);
    }
}

/// One thread's decoding scratch and markers; kept by the detector between frames.
#[derive(Debug, Clone)]
pub(crate) struct Decoder {
    scratch: Decoding,
    /// The markers of its run of quads, in quad order.
    found: Vec<Decoded>,
    /// The run of quads (start, end) of the current frame.
    range: (usize, usize),
}

/// Decodes `quads` on `threads` workers (contiguous runs of about equal length) and merges
/// their markers into `out` in quad order, as [`crate::Detector::decode_quads`]'s loop does;
/// the count of blurred readings is summed into `main`.
pub(crate) fn decode_all(
    img: &GrayView<'_>,
    ctx: &DecodeContext<'_>,
    quads: &[Quad],
    threads: usize,
    decoders: &mut Vec<Decoder>,
    main: &mut Decoding,
    out: &mut Vec<Decoded>,
) {
    let k = threads.clamp(1, quads.len().max(1));
    while decoders.len() < k {
        decoders.push(Decoder {
            scratch: Decoding::new(ctx.dictionaries()),
            found: Vec::new(),
            range: (0, 0),
        });
    }
    let decoders = &mut decoders[..k];
    for (j, d) in decoders.iter_mut().enumerate() {
        d.range = (j * quads.len() / k, (j + 1) * quads.len() / k);
    }
    let run = |d: &mut Decoder| {
        d.found.clear();
        d.scratch.blur.solved_quads = 0;
        for q in &quads[d.range.0..d.range.1] {
            if let Some(m) = ctx.decode(img, q, &mut d.scratch) {
                d.found.push(m);
            }
        }
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        decoders.par_iter_mut().for_each(run);
    }
    #[cfg(not(feature = "parallel"))]
    decoders.iter_mut().for_each(run);
    for d in decoders.iter() {
        main.blur.solved_quads += d.scratch.blur.solved_quads;
        for m in &d.found {
            push_unique(out, *m);
        }
    }
}
