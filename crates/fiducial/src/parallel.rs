//! The threaded parts of a detection on rayon's threads ([`crate::Search::parallel`],
//! issue #12) beyond banded binarization and labelling (each band's rows labelled on the
//! thread that cut them, [`crate::contour::Labeller::merge`]): the components of a frame are examined (traced,
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
use crate::image::GrayView;
use crate::refine::Refiner;
use crate::split::Rect;
use crate::stages::{DecodeContext, Decoding, Examined as Done, Quad, Scan};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Hands the items of `order` (indices, in that order) out to the workers, one at a time
/// as each is free, and calls `each` with the worker and the item; on rayon's threads with
/// the feature `parallel`, in turn without.
fn hand_out(workers: &mut [Worker], order: &[usize], each: impl Fn(&mut Worker, usize) + Sync) {
    let next = AtomicUsize::new(0);
    let run = |w: &mut Worker| {
        while let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
            each(w, i);
        }
    };
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
    /// Decoding scratch (made on the first frame that decodes).
    decoding: Option<Decoding>,
    /// Quads (and their reading, when decoded here) and re-cut boxes with the index of
    /// their component.
    quads: Vec<(usize, Quad, Option<Decoded>)>,
    retry: Vec<(usize, Rect)>,
    /// The markers of [`decode_all`], with their quad's index.
    found: Vec<(usize, Decoded)>,
}

impl Worker {
    /// Clears the results of the last frame, and readies the decoding scratch when this
    /// frame decodes (`ctx`).
    fn start(&mut self, ctx: Option<&DecodeContext<'_>>) {
        self.quads.clear();
        self.retry.clear();
        self.found.clear();
        if let Some(ctx) = ctx {
            self.decoding
                .get_or_insert_with(|| Decoding::new(ctx.dictionaries()));
        }
        if let Some(d) = self.decoding.as_mut() {
            d.blur.solved_quads = 0;
        }
    }

    /// The blurred readings of this frame's decoding.
    fn blurred(&self) -> usize {
        self.decoding.as_ref().map_or(0, |d| d.blur.solved_quads)
    }
}

/// `workers` grown to `k` and cut to them, each started ([`Worker::start`]).
fn ready<'w>(
    workers: &'w mut Vec<Worker>,
    k: usize,
    ctx: Option<&DecodeContext<'_>>,
) -> &'w mut [Worker] {
    if workers.len() < k {
        workers.resize_with(k, Worker::default);
    }
    let workers = &mut workers[..k];
    for w in workers.iter_mut() {
        w.start(ctx);
    }
    workers
}

/// Where [`examine_all`] puts its results: the quads, their markers when it decodes them (in
/// quad order) and the count of blurred readings among those, the re-cut boxes and the
/// flags of their components.
pub(crate) struct Examined<'a> {
    pub(crate) quads: &'a mut Vec<Quad>,
    pub(crate) readings: &'a mut Vec<Decoded>,
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
/// readings are those the detector's stage 5 would give. Components too small to
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
    let workers = ready(workers, threads.max(1), decode);
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
    hand_out(workers, &merged.order, |w, i| {
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
    });
    merged.quads.clear();
    merged.retry.clear();
    for w in workers.iter() {
        merged.quads.extend_from_slice(&w.quads);
        merged.retry.extend_from_slice(&w.retry);
        *to.blurred += w.blurred();
    }
    merged.quads.sort_unstable_by_key(|e| e.0);
    merged.retry.sort_unstable_by_key(|e| e.0);
    to.quads.extend(merged.quads.iter().map(|e| e.1));
    if decode.is_some() {
        to.readings.extend(merged.quads.iter().filter_map(|e| e.2));
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

/// Estimated cost of decoding a quad: the samples of the side check and of the pattern
/// refinement grow with the outline.
fn perimeter(q: &Quad) -> f64 {
    (0..4)
        .map(|i| (q.corners[(i + 1) % 4] - q.corners[i]).norm())
        .sum()
}

/// Decodes `quads` on `threads` workers (the largest quads first) and appends their markers
/// to `out` in quad order, as the detector's single-threaded loop does; the count of
/// blurred readings is summed into `main`. `merged` is scratch.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decode_all(
    img: &GrayView<'_>,
    ctx: &DecodeContext<'_>,
    quads: &[Quad],
    threads: usize,
    workers: &mut Vec<Worker>,
    merged: &mut Merge,
    main: &mut Decoding,
    out: &mut Vec<Decoded>,
) {
    let workers = ready(workers, threads.clamp(1, quads.len().max(1)), Some(ctx));
    merged.order.clear();
    merged.order.extend(0..quads.len());
    merged
        .order
        .sort_unstable_by(|&a, &b| perimeter(&quads[b]).total_cmp(&perimeter(&quads[a])));
    hand_out(workers, &merged.order, |w, i| {
        if let Some(m) = w
            .decoding
            .as_mut()
            .and_then(|d| ctx.decode(img, &quads[i], d))
        {
            w.found.push((i, m));
        }
    });
    merged.found.clear();
    for w in workers.iter() {
        main.blur.solved_quads += w.blurred();
        merged.found.extend_from_slice(&w.found);
    }
    merged.found.sort_unstable_by_key(|e| e.0);
    out.extend(merged.found.iter().map(|e| e.1));
}
