//! The threaded parts of [`Detector::detect_parallel`](crate::Detector::detect_parallel)
//! (issue #12) beyond banded binarization: the components of a frame are examined (traced,
//! fitted, refined) and the quads decoded by as many workers as there are threads, each
//! with its own scratch. The work is handed out as it goes (an atomic counter over the
//! items, the costliest first), so that a thread that drew cheap items takes more: a frame's
//! cost sits in the few components that are markers, and a fixed cut of the list into runs
//! left one thread idle for a fifth of the decoding on the benchmark frame. Each result
//! keeps its item's index, and the results are merged in index order, so the output is
//! exactly that of the single-threaded loop. A worker reads each quad as soon as it has
//! found it, so that examining and decoding are one stage for the threads (one meeting
//! fewer, and the readings balance with the tracing); only the quads the re-cut adds are
//! read afterwards, again on the threads. Without the crate feature `parallel` the workers
//! run in turn.

use crate::contour::Component;
use crate::decode::Decoded;
use crate::detector::{DecodeContext, Decoding, Examined as Done, Quad, Scan, push_unique};
use crate::image::GrayView;
use crate::refine::Refiner;
use crate::split::Rect;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Runs `run` on each worker, on rayon's threads with the feature `parallel`.
fn on_threads<W: Send>(workers: &mut [W], run: impl Fn(&mut W) + Sync + Send) {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        workers.par_iter_mut().for_each(run);
    }
    #[cfg(not(feature = "parallel"))]
    workers.iter_mut().for_each(run);
}

/// One thread's scratch and results; kept by the detector between frames.
#[derive(Debug, Default, Clone)]
pub(crate) struct Worker {
    contour: Vec<[i32; 2]>,
    refiner: Refiner,
    /// Decoding scratch, when quads are decoded as they are found.
    decoding: Option<Decoding>,
    /// Quads (and their reading, when decoded here) and re-cut boxes with the index of
    /// their component.
    quads: Vec<(usize, Quad, Option<Decoded>)>,
    retry: Vec<(usize, Rect)>,
}

/// Where [`examine_all`] puts its results: the quads, their readings when it decodes them
/// (aligned with the quads it appends) and the count of blurred readings among those, the
/// re-cut boxes and the flags of their components.
pub(crate) struct Examined<'a> {
    pub(crate) quads: &'a mut Vec<Quad>,
    pub(crate) readings: &'a mut Vec<Option<Decoded>>,
    pub(crate) blurred: &'a mut usize,
    pub(crate) retry: &'a mut Vec<Rect>,
    pub(crate) retried: &'a mut [bool],
}

/// Estimated cost of examining a component that is not too small to: tracing and
/// refinement grow with the outline, up to the refiner's cap on edge profiles.
fn weight(c: &Component) -> u32 {
    (c.x_max - c.x_min + c.y_max - c.y_min).min(512)
}

/// Examines `components` on `threads` workers and appends their quads and re-cut boxes to
/// `to` (flagging the boxes' components), in the order of the single-threaded loop. With
/// `decode`, each worker also reads each quad as soon as it has found it (one stage fewer
/// for the threads to meet at, and the readings balance with the rest of the work); the
/// readings are those [`crate::Detector::decode_quads`] would give. Components too small to
/// examine, which the loop drops first thing, are not handed out; the others go the largest
/// first. `merged` is scratch.
pub(crate) fn examine_all(
    scan: &Scan<'_, '_>,
    components: &[Component],
    threads: usize,
    workers: &mut Vec<Worker>,
    merged: &mut Merge,
    decode: Option<&DecodeContext<'_>>,
    to: Examined<'_>,
) {
    let k = threads.max(1);
    if workers.len() < k {
        workers.resize_with(k, Worker::default);
    }
    merged.order.clear();
    merged.order.extend(
        components
            .iter()
            .enumerate()
            .filter(|(_, c)| !scan.too_small(c))
            .map(|(i, _)| i),
    );
    merged
        .order
        .sort_unstable_by_key(|&i| std::cmp::Reverse(weight(&components[i])));
    let (order, next) = (&merged.order, AtomicUsize::new(0));
    on_threads(&mut workers[..k], |w: &mut Worker| {
        w.quads.clear();
        w.retry.clear();
        if let (Some(ctx), None) = (decode, &w.decoding) {
            w.decoding = Some(Decoding::new(ctx.dictionaries()));
        }
        if let Some(d) = w.decoding.as_mut() {
            d.blur.solved_quads = 0;
        }
        loop {
            let j = next.fetch_add(1, Ordering::Relaxed);
            let Some(&i) = order.get(j) else {
                break;
            };
            match scan.examine(&components[i], &mut w.contour, &mut w.refiner) {
                Done::Quad(q) => {
                    let reading = decode
                        .zip(w.decoding.as_mut())
                        .and_then(|(ctx, d)| ctx.decode(scan.img, &q, d));
                    w.quads.push((i, q, reading));
                }
                Done::Retry(r) => w.retry.push((i, r)),
                Done::Dropped => {}
            }
        }
    });
    merged.quads.clear();
    merged.retry.clear();
    for w in &workers[..k] {
        merged.quads.extend_from_slice(&w.quads);
        merged.retry.extend_from_slice(&w.retry);
        if decode.is_some() {
            *to.blurred += w.decoding.as_ref().map_or(0, |d| d.blur.solved_quads);
        }
    }
    merged.quads.sort_unstable_by_key(|e| e.0);
    merged.retry.sort_unstable_by_key(|e| e.0);
    to.quads.extend(merged.quads.iter().map(|e| e.1));
    if decode.is_some() {
        to.readings.extend(merged.quads.iter().map(|e| e.2));
    }
    to.retry.extend(merged.retry.iter().map(|e| e.1));
    for e in &merged.retry {
        to.retried[e.0] = true;
    }
}

/// Scratch of the index-ordered merges, kept by the detector between frames.
#[derive(Debug, Default, Clone)]
pub(crate) struct Merge {
    quads: Vec<(usize, Quad, Option<Decoded>)>,
    retry: Vec<(usize, Rect)>,
    found: Vec<(usize, Decoded)>,
    /// Component or quad indices, costliest first.
    order: Vec<usize>,
}

/// One thread's decoding scratch and markers; kept by the detector between frames.
#[derive(Debug, Clone)]
pub(crate) struct Decoder {
    scratch: Decoding,
    /// The markers it read, with their quad's index.
    found: Vec<(usize, Decoded)>,
}

/// Estimated cost of decoding a quad: the samples of the side check and of the pattern
/// refinement grow with the outline.
fn perimeter(q: &Quad) -> f64 {
    (0..4)
        .map(|i| (q.corners[(i + 1) % 4] - q.corners[i]).norm())
        .sum()
}

/// Decodes `quads` on `threads` workers (the largest quads first) and merges their markers
/// into `out` in quad order, as [`crate::Detector::decode_quads`]'s loop does; the count of
/// blurred readings is summed into `main`. `merged` is scratch.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode_all(
    img: &GrayView<'_>,
    ctx: &DecodeContext<'_>,
    quads: &[Quad],
    threads: usize,
    decoders: &mut Vec<Decoder>,
    merged: &mut Merge,
    main: &mut Decoding,
    out: &mut Vec<Decoded>,
) {
    let k = threads.clamp(1, quads.len().max(1));
    while decoders.len() < k {
        decoders.push(Decoder {
            scratch: Decoding::new(ctx.dictionaries()),
            found: Vec::new(),
        });
    }
    merged.order.clear();
    merged.order.extend(0..quads.len());
    merged
        .order
        .sort_unstable_by(|&a, &b| perimeter(&quads[b]).total_cmp(&perimeter(&quads[a])));
    let (order, next) = (&merged.order, AtomicUsize::new(0));
    on_threads(&mut decoders[..k], |d: &mut Decoder| {
        d.found.clear();
        d.scratch.blur.solved_quads = 0;
        loop {
            let j = next.fetch_add(1, Ordering::Relaxed);
            let Some(&i) = order.get(j) else {
                break;
            };
            if let Some(m) = ctx.decode(img, &quads[i], &mut d.scratch) {
                d.found.push((i, m));
            }
        }
    });
    merged.found.clear();
    for d in &decoders[..k] {
        main.blur.solved_quads += d.scratch.blur.solved_quads;
        merged.found.extend_from_slice(&d.found);
    }
    merged.found.sort_unstable_by_key(|e| e.0);
    for (_, m) in &merged.found {
        push_unique(out, *m);
    }
}
