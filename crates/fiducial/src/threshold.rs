//! Grey conversion and binarization: the first two stages of the detector (spec 3.4, steps
//! 1-2).
//!
//! The default [`Threshold::Adaptive`] is the AprilTag 3 scheme, made noise-tolerant: the
//! frame is first smoothed by a 3x3 box filter (noise sigma drops threefold, which keeps flat
//! areas from breaking into speckle), then cut into square tiles; each tile's threshold is
//! the midpoint of the minimum and maximum over its 3x3 tile neighbourhood. A neighbourhood
//! whose contrast (max - min) is below `min_contrast` is flat and is left white, so blank wall
//! or the inside of a large dark area never produces spurious dark blobs. A tile sees only
//! its neighbourhood, so a lighting gradient of 4:1 across the frame changes nothing.
//!
//! [`Threshold::Otsu`] is the paper's global threshold (one histogram, one cut), kept as an
//! option for comparison; it fails under uneven lighting, which is why it is not the default.
//!
//! Every buffer is owned by a [`Binarizer`] and reused from frame to frame: after the first
//! frame of a given size, binarization allocates nothing.

use crate::image::{GrayView, ImageError};

/// How grey levels are cut into dark (candidate marker border) and light.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Threshold {
    /// Local tile min/max threshold (the default; robust to lighting gradients).
    Adaptive {
        /// Tile side in pixels (the neighbourhood is 3x3 tiles). Default 8.
        tile_size: usize,
        /// Neighbourhoods whose max - min grey level is below this are flat and left light.
        /// Default 30 (above the range of sensor noise of sigma 10 after smoothing).
        min_contrast: u8,
    },
    /// The paper's global Otsu threshold over the whole (smoothed) frame.
    Otsu,
}

impl Threshold {
    /// Side of the square tiles the frame is cut into, pixels: the adaptive tile size
    /// (clamped to 2-64), and 8 for Otsu (no tiles, but bands of binarization are cut at
    /// multiples of 8 rows).
    pub(crate) fn tile_side(&self) -> usize {
        match *self {
            Threshold::Adaptive { tile_size, .. } => tile_size.clamp(2, 64),
            Threshold::Otsu => 8,
        }
    }
}

impl Default for Threshold {
    fn default() -> Self {
        Threshold::Adaptive {
            tile_size: 8,
            min_contrast: 30,
        }
    }
}

/// How much darker (grey levels) the 1x3 or 3x1 box must be than the 3x3 box for a pixel
/// to be cut on the narrow box: well above what sensor noise makes of their difference
/// (about half the noise sigma), so that only a real line of dark pixels takes this path.
const LINE_STEP: u32 = 12;

/// `9 * LINE_STEP`: the step on the scale of sums of nine pixels.
const LINE_STEP_9: u16 = 9 * LINE_STEP as u16;

/// Value of a dark pixel in the binary image (light pixels are 0).
pub const DARK: u8 = 1;

/// Owns the scratch buffers of binarization so that repeated frames allocate nothing.
///
/// The adaptive threshold reads the frame in two passes and keeps no frame-sized buffer.
/// The first computes each pixel's 3x3 box mean and folds it into its tile's minimum and
/// maximum, and nothing else. The second visits each tile row once its thresholds are known
/// (single-threaded: as soon as the tile row below it is done, while its pixels are still in
/// cache) and computes the line-preserving level only in tiles that have a threshold: in a
/// tile whose neighbourhood is flat nothing is dark, whatever the level, and a frame of
/// markers on a plain background is mostly such tiles.
#[derive(Debug, Default, Clone)]
pub struct Binarizer {
    /// The smoothed frame, kept only for [`Threshold::Otsu`] (its histogram).
    smooth: Vec<u8>,
    /// Scratch rows of each band of rows (one band unless [`Binarizer::binarize_parallel`]).
    bands: Vec<Band>,
}

/// One band's work in [`Binarizer::binarize_parallel`]: its index, its rows of the output,
/// its scratch, its caller's state.
type CutBand<'a, S> = (usize, ((&'a mut [u8], &'a mut Band), &'a mut S));

/// The scratch rows one band of rows needs.
#[derive(Debug, Default, Clone)]
struct Band {
    /// Three rows of horizontal 3-sums (a ring).
    hsum: Vec<u16>,
    /// Element-wise minimum of the box means of a tile row's rows.
    row_min: Vec<u8>,
    /// Element-wise maximum of the box means of a tile row's rows.
    row_max: Vec<u8>,
    /// The cut's scratch.
    cut: CutScratch,
    /// Tile minima and maxima of the band's tile rows and one more above and below, at
    /// their places in a whole frame's arrays (so that bands never share a tile row).
    tile_min: Vec<u8>,
    tile_max: Vec<u8>,
}

/// The scratch rows of the cut of one tile row.
#[derive(Debug, Default, Clone)]
struct CutScratch {
    /// The minimum over the tiles above, at and below, per tile.
    col_min: Vec<u8>,
    /// The maximum over the tiles above, at and below, per tile.
    col_max: Vec<u8>,
    /// The tile row's thresholds, one per tile.
    tile_thr: Vec<u8>,
    /// Per pixel, the least nine-pixel sum whose box mean reaches the pixel's threshold.
    sum_thr: Vec<i16>,
    /// Per pixel, three times its threshold (the same test on the scale of 3-sums).
    line_thr: Vec<i16>,
    /// Three rows of horizontal 3-sums over a run of tiles (a ring).
    hsum: Vec<i16>,
    /// The pixel ranges `[x0, x1)` of the runs of tiles that have a threshold.
    runs: Vec<(usize, usize)>,
}

/// The adaptive rule's tile geometry and contrast floor.
#[derive(Debug, Clone, Copy)]
struct Tiles {
    /// Tile side in pixels.
    side: usize,
    /// Tiles per row and per column.
    tx: usize,
    ty: usize,
    min_contrast: u8,
    /// Frame width and height in pixels.
    width: usize,
    height: usize,
}

impl Binarizer {
    /// An empty binarizer; buffers grow on the first frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes the binary image of `img` into `out` (`width * height` bytes, row-major,
    /// [`DARK`] for dark pixels, 0 for light). `out` keeps its capacity between calls.
    pub fn binarize(&mut self, img: &GrayView<'_>, threshold: Threshold, out: &mut Vec<u8>) {
        self.run(img, threshold, out, &mut [()], &|_, _, _| {});
    }

    /// [`Binarizer::binarize`] on up to `bands` threads of the current rayon pool (with the
    /// crate feature `parallel`; without it the bands run one after the other): the frame
    /// is cut into horizontal bands of whole tile rows, and each band is binarized on its
    /// own thread in one pass, as the whole frame is on one thread (with
    /// [`Threshold::Otsu`], one thread). A band's first and last tile rows need the tile
    /// extremes of the rows above and below it, so each band also computes those of its
    /// neighbours' edge rows (one tile row more per band boundary): one pass on each
    /// thread, not one for the extremes and one for the cut, and no thread waits for
    /// another. Every stage reads the same pixels as the single-threaded pass, so the
    /// output is identical to [`Binarizer::binarize`]'s.
    pub fn binarize_parallel(
        &mut self,
        img: &GrayView<'_>,
        threshold: Threshold,
        out: &mut Vec<u8>,
        bands: usize,
    ) {
        // One (empty, allocation-free) state per band.
        let mut none = vec![(); bands.max(1)];
        self.run(img, threshold, out, &mut none, &|_, _, _| {});
    }

    /// [`Binarizer::binarize_parallel`], and then, on the thread that cut each band and
    /// while its rows are still in that thread's cache, `after(&mut states[b], y0, rows)`
    /// with band `b`'s first row and its rows of the output (whole rows). Returns the
    /// number of bands, `states.len()` at most (one band, the whole frame, with
    /// [`Threshold::Otsu`]); the detector labels each band's rows this way.
    pub(crate) fn binarize_parallel_then<S: Send>(
        &mut self,
        img: &GrayView<'_>,
        threshold: Threshold,
        out: &mut Vec<u8>,
        states: &mut [S],
        after: &(impl Fn(&mut S, usize, &[u8]) + Sync),
    ) -> usize {
        self.run(img, threshold, out, states, after)
    }

    /// Binarizes in up to `states.len()` bands (see [`Binarizer::binarize_parallel`]) and
    /// calls `after` on each band's rows with its state; returns the number of bands.
    fn run<S: Send>(
        &mut self,
        img: &GrayView<'_>,
        threshold: Threshold,
        out: &mut Vec<u8>,
        states: &mut [S],
        after: &(impl Fn(&mut S, usize, &[u8]) + Sync),
    ) -> usize {
        let (w, h) = (img.width(), img.height());
        // Every byte of these is written below: resize only (no clear and refill).
        out.resize(w * h, 0);
        let side = threshold.tile_side();
        let min_contrast = match threshold {
            Threshold::Adaptive { min_contrast, .. } => Some(min_contrast),
            Threshold::Otsu => None,
        };
        let (tx, ty) = (w.div_ceil(side), h.div_ceil(side));
        let band_tiles = ty.div_ceil(states.len().clamp(1, ty));
        let band_rows = band_tiles * side;
        let count = h.div_ceil(band_rows);
        if self.bands.len() < count {
            self.bands.resize_with(count, Band::default);
        }
        let Some(min_contrast) = min_contrast else {
            // Otsu: the smoothed frame's histogram gives one cut for every level.
            self.smooth.resize(w * h, 0);
            levels_rows(
                img,
                0,
                &mut out[..],
                Some(&mut self.smooth[..]),
                &mut self.bands[0].hsum,
            );
            let t = otsu_level(&self.smooth);
            for o in out.iter_mut() {
                *o = u8::from(*o <= t);
            }
            if let Some(s) = states.first_mut() {
                after(s, 0, out);
            }
            return 1;
        };
        let tiles = Tiles {
            side,
            tx,
            ty,
            min_contrast,
            width: w,
            height: h,
        };
        if count == 1 {
            extremes_and_cut(img, &mut out[..], &tiles, (0, ty), &mut self.bands[0]);
            if let Some(s) = states.first_mut() {
                after(s, 0, out);
            }
            return 1;
        }
        // Each band on its own thread, in one pass as on one thread: the tile extremes of
        // its tile rows (and of the row above and below it, which its neighbours compute
        // too), and the cut of each tile row as soon as the row below it is known.
        let cut_band = |(b, ((o, band), state)): CutBand<'_, S>| {
            let j0 = b * band_tiles;
            extremes_and_cut(img, o, &tiles, (j0, (j0 + band_tiles).min(ty)), band);
            after(state, j0 * side, o);
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            out.par_chunks_mut(band_rows * w)
                .zip(self.bands.par_iter_mut())
                .zip(states.par_iter_mut())
                .enumerate()
                .for_each(cut_band);
        }
        #[cfg(not(feature = "parallel"))]
        out.chunks_mut(band_rows * w)
            .zip(self.bands.iter_mut())
            .zip(states.iter_mut())
            .enumerate()
            .for_each(cut_band);
        count
    }

    /// The smoothed frame (3x3 box filter) of the last call with [`Threshold::Otsu`],
    /// row-major, `width` per row; empty before the first such call. The adaptive threshold
    /// does not keep the smoothed frame (it needs only its tile minima and maxima).
    pub fn smoothed(&self) -> &[u8] {
        &self.smooth
    }
}

/// The ring of three rows of horizontal 3-sums (end pixels replicated) that the 3x3 box
/// needs: slot 0 holds row `y - 1`'s, slot 1 row `y`'s, and slot 2 receives row `y + 1`'s
/// while row `y` is computed (rows clamped to the frame).
struct Ring<'a> {
    slots: [&'a mut [u16]; 3],
}

impl<'a> Ring<'a> {
    /// The ring ready for row `y0`.
    #[inline(always)]
    fn start(img: &GrayView<'_>, y0: usize, hsum: &'a mut Vec<u16>) -> Self {
        let w = img.width();
        hsum.resize(3 * w, 0);
        let (s0, rest) = hsum.split_at_mut(w);
        let (s1, s2) = rest.split_at_mut(w);
        hrow(img.row(y0.saturating_sub(1)), s0);
        hrow(img.row(y0), s1);
        Self {
            slots: [s0, s1, s2],
        }
    }

    /// The box means of the rows `y0 .. y1`, folded into the element-wise minimum `row_min`
    /// and maximum `row_max` (one row each; combined with what they hold).
    #[inline(always)]
    fn means(
        &mut self,
        img: &GrayView<'_>,
        (y0, y1): (usize, usize),
        row_min: &mut [u8],
        row_max: &mut [u8],
    ) {
        let h = img.height();
        for y in y0..y1 {
            let [s0, s1, s2] = &mut self.slots;
            mean_row([s0, s1], s2, img.row((y + 1).min(h - 1)), row_min, row_max);
            self.slots.rotate_left(1);
        }
    }

    /// Rows `y0 ..` of the frame, as many as `out` holds (whole rows): their line-preserving
    /// levels into `out`, with `SMOOTH` their box means into `smooth` (as long as `out`).
    fn levels<const SMOOTH: bool>(
        &mut self,
        img: &GrayView<'_>,
        y0: usize,
        out: &mut [u8],
        smooth: &mut [u8],
    ) {
        let (w, h) = (img.width(), img.height());
        for (i, o) in out.chunks_exact_mut(w).enumerate() {
            let y = y0 + i;
            let px = [
                img.row(y.saturating_sub(1)),
                img.row(y),
                img.row((y + 1).min(h - 1)),
            ];
            let sm = if SMOOTH {
                &mut smooth[i * w..(i + 1) * w]
            } else {
                &mut smooth[..0]
            };
            let [s0, s1, s2] = &mut self.slots;
            box_row::<SMOOTH>([s0, s1], s2, px, o, sm);
            self.slots.rotate_left(1);
        }
    }
}

/// The line-preserving levels of the rows `y0 ..` of `img` that `out` holds (whole rows)
/// into `out`, and with `smooth` their box means into it.
fn levels_rows(
    img: &GrayView<'_>,
    y0: usize,
    out: &mut [u8],
    smooth: Option<&mut [u8]>,
    hsum: &mut Vec<u16>,
) {
    let mut ring = Ring::start(img, y0, hsum);
    match smooth {
        Some(smooth) => ring.levels::<true>(img, y0, out, smooth),
        None => ring.levels::<false>(img, y0, out, &mut []),
    }
}

/// The adaptive binarization of tile rows `j0 .. j1` (`out` holds their pixel rows) on one
/// thread: each tile row's extremes (from the row above `j0` to the row below `j1 - 1`, into
/// the band's whole-frame tile arrays), and the cut of the tile row above it as soon as they
/// are known (its pixels are then still in cache).
///
/// Compiled twice on x86-64: for the baseline (SSE2) and for AVX2, which the CPU is asked
/// for at run time (std caches the answer): the 16-bit loops then take 16 pixels at a time,
/// and binarization of the demo frame at 640x480 took 62 us instead of 82. The code is the
/// same source, inlined into each, and integer-only, so both give the same bits (a proptest
/// compares them). The labeller's row scan and the re-cut's tiles and cut were tried the
/// same way and gained nothing measurable. The call below is the crate's only `unsafe`.
fn extremes_and_cut(
    img: &GrayView<'_>,
    out: &mut [u8],
    tiles: &Tiles,
    rows: (usize, usize),
    band: &mut Band,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked at run time just above), which is all that
        // calling a function compiled with `target_feature(enable = "avx2")` requires.
        #[allow(unsafe_code)]
        unsafe {
            extremes_and_cut_avx2(img, out, tiles, rows, band);
        }
        return;
    }
    extremes_and_cut_body(img, out, tiles, rows, band);
}

/// [`extremes_and_cut_body`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn extremes_and_cut_avx2(
    img: &GrayView<'_>,
    out: &mut [u8],
    tiles: &Tiles,
    rows: (usize, usize),
    band: &mut Band,
) {
    extremes_and_cut_body(img, out, tiles, rows, band);
}

/// The body of [`extremes_and_cut`], inlined (with what it calls) into each compilation.
#[inline(always)]
fn extremes_and_cut_body(
    img: &GrayView<'_>,
    out: &mut [u8],
    tiles: &Tiles,
    (j0, j1): (usize, usize),
    band: &mut Band,
) {
    let (w, side, tx) = (img.width(), tiles.side, tiles.tx);
    let rows_per = side * w;
    let Band {
        hsum,
        row_min,
        row_max,
        cut,
        tile_min,
        tile_max,
    } = band;
    tile_min.resize(tx * tiles.ty, 0);
    tile_max.resize(tx * tiles.ty, 0);
    // The extremes needed: the band's tile rows and their neighbours in the frame.
    let (e0, e1) = (j0.saturating_sub(1), (j1 + 1).min(tiles.ty));
    let mut ring = Ring::start(img, e0 * side, hsum);
    row_min.resize(w, 0);
    row_max.resize(w, 0);
    for j in e0..e1 {
        row_min.fill(u8::MAX);
        row_max.fill(0);
        let y = j * side;
        ring.means(img, (y, (y + side).min(tiles.height)), row_min, row_max);
        let k = j * tx..(j + 1) * tx;
        tile_extremes(
            row_min,
            row_max,
            side,
            &mut tile_min[k.clone()],
            &mut tile_max[k],
        );
        if j > j0 {
            let i = j - 1 - j0;
            let rows = &mut out[i * rows_per..(i + 1) * rows_per];
            cut_tile_row(img, j - 1, rows, tiles, tile_min, tile_max, cut);
        }
    }
    if e1 == j1 {
        // The frame's last tile row: its neighbour below is itself.
        let i = j1 - 1 - j0;
        cut_tile_row(
            img,
            j1 - 1,
            &mut out[i * rows_per..],
            tiles,
            tile_min,
            tile_max,
            cut,
        );
    }
}

/// Each tile's minimum and maximum (tiles of `side` pixels, the last one cut short) from the
/// element-wise minimum and maximum of its rows.
#[inline(always)]
fn tile_extremes(row_min: &[u8], row_max: &[u8], side: usize, mins: &mut [u8], maxs: &mut [u8]) {
    if side == 8 {
        // The default tile: whole tiles as fixed-size arrays.
        let (cmin, cmax) = (row_min.chunks_exact(8), row_max.chunks_exact(8));
        let (rmin, rmax) = (cmin.remainder(), cmax.remainder());
        for (((a, b), mn), mx) in cmin.zip(cmax).zip(mins.iter_mut()).zip(maxs.iter_mut()) {
            *mn = a.iter().copied().fold(u8::MAX, u8::min);
            *mx = b.iter().copied().fold(0, u8::max);
        }
        if !rmin.is_empty() {
            let last = mins.len() - 1;
            mins[last] = rmin.iter().copied().fold(u8::MAX, u8::min);
            maxs[last] = rmax.iter().copied().fold(0, u8::max);
        }
        return;
    }
    for (((a, b), mn), mx) in row_min
        .chunks(side)
        .zip(row_max.chunks(side))
        .zip(mins.iter_mut())
        .zip(maxs.iter_mut())
    {
        *mn = a.iter().copied().fold(u8::MAX, u8::min);
        *mx = b.iter().copied().fold(0, u8::max);
    }
}

/// The cut of tile row `j`, whose pixels `rows` holds (levels in, binary out): each tile's
/// threshold is the midpoint of the minimum and maximum over its 3x3 tile neighbourhood, or
/// 0 ("nothing here is dark") where their difference is below `min_contrast`; a pixel is
/// dark where its level is below its tile's threshold.
#[inline(always)]
fn cut_tile_row(
    img: &GrayView<'_>,
    j: usize,
    rows: &mut [u8],
    tiles: &Tiles,
    tile_min: &[u8],
    tile_max: &[u8],
    scratch: &mut CutScratch,
) {
    let Tiles {
        side,
        tx,
        ty,
        min_contrast,
        width: w,
        ..
    } = *tiles;
    let CutScratch {
        col_min,
        col_max,
        tile_thr,
        sum_thr,
        line_thr,
        hsum,
        runs,
    } = scratch;
    // The neighbourhood's extremes: over the tile rows above, at and below (clamped)...
    fn tile_row(v: &[u8], k: usize, tx: usize) -> &[u8] {
        &v[k * tx..(k + 1) * tx]
    }
    let (up, down) = (j.saturating_sub(1), (j + 1).min(ty - 1));
    col_min.resize(tx, 0);
    col_max.resize(tx, 0);
    for (((c, a), b), d) in col_min
        .iter_mut()
        .zip(tile_row(tile_min, up, tx))
        .zip(tile_row(tile_min, j, tx))
        .zip(tile_row(tile_min, down, tx))
    {
        *c = (*a).min(*b).min(*d);
    }
    for (((c, a), b), d) in col_max
        .iter_mut()
        .zip(tile_row(tile_max, up, tx))
        .zip(tile_row(tile_max, j, tx))
        .zip(tile_row(tile_max, down, tx))
    {
        *c = (*a).max(*b).max(*d);
    }
    // ...then over the tiles left, at and right (clamped), and the threshold.
    tile_thr.resize(tx, 0);
    let thr = |lo: u8, hi: u8| {
        if hi - lo < min_contrast {
            0
        } else {
            (u16::from(lo) + u16::from(hi)).div_ceil(2) as u8
        }
    };
    if tx == 1 {
        tile_thr[0] = thr(col_min[0], col_max[0]);
    } else {
        tile_thr[0] = thr(col_min[0].min(col_min[1]), col_max[0].max(col_max[1]));
        tile_thr[tx - 1] = thr(
            col_min[tx - 2].min(col_min[tx - 1]),
            col_max[tx - 2].max(col_max[tx - 1]),
        );
        let n = tx - 2;
        let (l, c, r) = (&col_min[..n], &col_min[1..n + 1], &col_min[2..]);
        let (lm, cm, rm) = (&col_max[..n], &col_max[1..n + 1], &col_max[2..]);
        let inner = &mut tile_thr[1..n + 1];
        for i in 0..n {
            inner[i] = thr(l[i].min(c[i]).min(r[i]), lm[i].max(cm[i]).max(rm[i]));
        }
    }
    // The runs of tiles that have a threshold; elsewhere nothing is dark.
    runs.clear();
    let mut i = 0;
    while i < tx {
        if tile_thr[i] == 0 {
            i += 1;
            continue;
        }
        let start = i;
        while i < tx && tile_thr[i] != 0 {
            i += 1;
        }
        runs.push((start * side, (i * side).min(w)));
    }
    if runs.is_empty() {
        rows.fill(0);
        return;
    }
    // The thresholds per pixel, as the two tests of the cut need them, then each run's
    // levels computed and compared, one row after the other; the rest of each row is light.
    for (v, t) in [
        (&mut *sum_thr, SumOrLine::Sum),
        (&mut *line_thr, SumOrLine::Line),
    ] {
        v.resize(w, 0);
        let at = |k: usize| t.scale(tile_thr[k]);
        if side == 8 {
            let mut chunks = v.chunks_exact_mut(8);
            for (k, c) in chunks.by_ref().enumerate() {
                c.copy_from_slice(&[at(k); 8]);
            }
            let last = at(tx - 1);
            chunks.into_remainder().iter_mut().for_each(|v| *v = last);
        } else {
            for (k, c) in v.chunks_mut(side).enumerate() {
                let t = at(k);
                c.iter_mut().for_each(|v| *v = t);
            }
        }
    }
    let y0 = j * side;
    let n_rows = rows.len() / w;
    for &(x0, x1) in runs.iter() {
        cut_run(img, (y0, n_rows), (x0, x1), (sum_thr, line_thr), hsum, rows);
    }
    for row in rows.chunks_exact_mut(w) {
        let mut done = 0;
        for &(x0, x1) in runs.iter() {
            row[done..x0].fill(0);
            done = x1;
        }
        row[done..].fill(0);
    }
}

/// A tile threshold `t` on the scale of one of the two tests of the cut.
#[derive(Debug, Clone, Copy)]
enum SumOrLine {
    /// The least nine-pixel sum `s` whose box mean is at least `t`: the mean is below `t`
    /// exactly where `s` is below this. As `box_mean(s) = floor(7282 s / 65536)`, it is
    /// `ceil(65536 t / 7282)`.
    Sum,
    /// `3 t`: a 3-sum `l` has `l / 3 < t` exactly where `l < 3 t`.
    Line,
}

impl SumOrLine {
    #[inline]
    fn scale(self, t: u8) -> i16 {
        match self {
            Self::Sum => (u32::from(t) * 65536).div_ceil(7282) as i16,
            Self::Line => 3 * i16::from(t),
        }
    }
}

/// The cut of the pixels `x0 .. x1` of the rows `y0 .. y0 + n` (`rows` holds those rows,
/// whole): dark where the line-preserving level is below the threshold. With the thresholds
/// scaled ([`SumOrLine`]), that is where the nine-pixel sum `s` is below `sum_thr` (the box
/// mean is below the threshold, and the level is never above the mean), or where the line
/// rule holds (`3 least + 9 LINE_STEP < s`) and the least 3-sum is below `line_thr` (its
/// third is below the threshold): no division and no choice of level per pixel.
///
/// The horizontal 3-sums go through a ring of three rows over the run (`hsum`), so that each
/// row's are computed once; the inner loops run in 16-bit arithmetic over slices of one
/// length, so they vectorise.
#[inline(always)]
fn cut_run(
    img: &GrayView<'_>,
    (y0, n): (usize, usize),
    (x0, x1): (usize, usize),
    (sum_thr, line_thr): (&[i16], &[i16]),
    hsum: &mut Vec<i16>,
    rows: &mut [u8],
) {
    let (w, h) = (img.width(), img.height());
    let len = x1 - x0;
    hsum.resize(3 * len, 0);
    let (s0, rest) = hsum.split_at_mut(len);
    let (s1, s2) = rest.split_at_mut(len);
    let mut slots = [s0, s1, s2];
    hsum_range(img.row(y0.saturating_sub(1)), x0, slots[0]);
    hsum_range(img.row(y0), x0, slots[1]);
    let (st, lt) = (&sum_thr[x0..x1], &line_thr[x0..x1]);
    for (i, row) in rows.chunks_exact_mut(w).take(n).enumerate() {
        let y = y0 + i;
        let below = img.row((y + 1).min(h - 1));
        hsum_range(below, x0, slots[2]);
        let (u, m, d) = (
            &img.row(y.saturating_sub(1))[x0..x1],
            &img.row(y)[x0..x1],
            &below[x0..x1],
        );
        let (a, b, c) = (&slots[0][..len], &slots[1][..len], &slots[2][..len]);
        let out = &mut row[x0..x1];
        for k in 0..len {
            let s = a[k] + b[k] + c[k];
            let vert = i16::from(u[k]) + i16::from(m[k]) + i16::from(d[k]);
            let least = b[k].min(vert);
            // Bitwise, not short-circuit: no branch in the loop.
            let line = (3 * least + (LINE_STEP_9 as i16) < s) & (least < lt[k]);
            out[k] = u8::from((s < st[k]) | line);
        }
        slots.rotate_left(1);
    }
}

/// Horizontal 3-sums (end pixels of the row replicated) of the pixels `x0 .. x0 +
/// dst.len()` of the row `src`, into `dst`.
#[inline(always)]
fn hsum_range(src: &[u8], x0: usize, dst: &mut [i16]) {
    let w = src.len();
    let x1 = x0 + dst.len();
    let at = |x: usize| i16::from(src[x]);
    let one = |x: usize| at(x.saturating_sub(1)) + at(x) + at((x + 1).min(w - 1));
    // The pixels with both row neighbours, `a .. b`; the row's end pixels apart.
    let (a, b) = (x0.max(1), x1.min(w - 1));
    if x0 == 0 {
        dst[0] = one(0);
    }
    if x1 == w && w > 1 {
        dst[w - 1 - x0] = one(w - 1);
    }
    if a >= b {
        return;
    }
    let (l, c, r) = (&src[a - 1..b - 1], &src[a..b], &src[a + 1..b + 1]);
    let out = &mut dst[a - x0..b - x0];
    for k in 0..out.len() {
        out[k] = i16::from(l[k]) + i16::from(c[k]) + i16::from(r[k]);
    }
}

/// Horizontal 3-sums of `src` with the end pixels replicated, into `dst` (same length).
#[inline(always)]
fn hrow(src: &[u8], dst: &mut [u16]) {
    let w = dst.len();
    let src = &src[..w];
    if w == 1 {
        dst[0] = 3 * u16::from(src[0]);
        return;
    }
    dst[0] = 2 * u16::from(src[0]) + u16::from(src[1]);
    let (a, b, c) = (&src[..w - 2], &src[1..w - 1], &src[2..]);
    let inner = &mut dst[1..w - 1];
    for i in 0..inner.len() {
        inner[i] = u16::from(a[i]) + u16::from(b[i]) + u16::from(c[i]);
    }
    dst[w - 1] = u16::from(src[w - 2]) + 2 * u16::from(src[w - 1]);
}

/// The 3x3 box mean of a pixel from its nine-pixel sum: `s / 9` without a division (a 16-bit
/// multiply-high: 7282 / 65536 = 0.11111).
#[inline(always)]
fn box_mean(s: u16) -> u8 {
    ((u32::from(s) * 7282) >> 16) as u8
}

/// The box mean and the line-preserving level of one pixel from its nine-pixel sum `s`, the
/// 1x3 sum along its row `horiz` and the 3x1 sum along its column `vert`.
///
/// The level is the darkest of the 3x3 box and the 3x1 and 1x3 ones (sums times 3, so that
/// all three compare on one scale): a dark line two pixels wide along either axis keeps its
/// level in the 1x3 box along it, where the 3x3 box would mix in its light surround. All
/// terms stay below 2^16.
#[inline(always)]
fn levels(s: u16, horiz: u16, vert: u16) -> (u8, u8) {
    let mean = box_mean(s);
    let least = horiz.min(vert);
    let level = if 3 * least + LINE_STEP_9 < s {
        (least / 3) as u8
    } else {
        mean
    };
    (mean, level)
}

/// One row of the 3x3 box: from the horizontal sums of the rows above and at it (`hs`) and
/// the pixels of the rows above, at and below it (`px`), the horizontal sums of the row
/// below into `next`, the line-preserving levels into `out`, with `SMOOTH` the box means
/// into `smooth`.
///
/// The inner loop runs over slices of one length in 16-bit arithmetic, so it vectorises; the
/// two end pixels (replicated borders) are done apart.
#[inline(always)]
fn box_row<const SMOOTH: bool>(
    hs: [&[u16]; 2],
    next: &mut [u16],
    px: [&[u8]; 3],
    out: &mut [u8],
    smooth: &mut [u8],
) {
    let w = out.len();
    let (h0, h1) = (&hs[0][..w], &hs[1][..w]);
    let (u, m, d) = (&px[0][..w], &px[1][..w], &px[2][..w]);
    let smooth = &mut smooth[..if SMOOTH { w } else { 0 }];
    hrow(d, next);
    let h2 = &next[..w];
    for x in 0..w {
        let vert = u16::from(u[x]) + u16::from(m[x]) + u16::from(d[x]);
        let (mean, level) = levels(h0[x] + h1[x] + h2[x], h1[x], vert);
        out[x] = level;
        if SMOOTH {
            smooth[x] = mean;
        }
    }
}

/// One row of box means, folded into the element-wise minimum `row_min` and maximum
/// `row_max`: from the horizontal sums of the rows above and at it (`hs`) and the pixels of
/// the row below (`below`), whose horizontal sums go into `next` on the way.
///
/// The inner loop runs over slices of one length in 16-bit arithmetic, so it vectorises; the
/// two end pixels (replicated borders) are done apart.
#[inline(always)]
fn mean_row(
    hs: [&[u16]; 2],
    next: &mut [u16],
    below: &[u8],
    row_min: &mut [u8],
    row_max: &mut [u8],
) {
    let w = row_min.len();
    let (h0, h1, h2, d) = (&hs[0][..w], &hs[1][..w], &mut next[..w], &below[..w]);
    let row_max = &mut row_max[..w];
    let mean = box_mean;
    let mut put = |x: usize, s: u16| {
        row_min[x] = row_min[x].min(mean(s));
        row_max[x] = row_max[x].max(mean(s));
    };
    if w == 1 {
        h2[0] = 3 * u16::from(d[0]);
        put(0, h0[0] + h1[0] + h2[0]);
        return;
    }
    h2[0] = 2 * u16::from(d[0]) + u16::from(d[1]);
    h2[w - 1] = u16::from(d[w - 2]) + 2 * u16::from(d[w - 1]);
    put(0, h0[0] + h1[0] + h2[0]);
    put(w - 1, h0[w - 1] + h1[w - 1] + h2[w - 1]);
    // The inner pixels 1 .. w - 1, on slices offset by one.
    let n = w - 2;
    let (dl, dc, dr) = (&d[..n], &d[1..n + 1], &d[2..]);
    let (a, b, c) = (&h0[1..n + 1], &h1[1..n + 1], &mut h2[1..n + 1]);
    let (rmin, rmax) = (&mut row_min[1..n + 1], &mut row_max[1..n + 1]);
    for i in 0..n {
        let below = u16::from(dl[i]) + u16::from(dc[i]) + u16::from(dr[i]);
        c[i] = below;
        let m = mean(a[i] + b[i] + below);
        rmin[i] = rmin[i].min(m);
        rmax[i] = rmax[i].max(m);
    }
}

/// Otsu's threshold of a set of grey levels: the level `t` that maximises the between-class
/// variance of `{v <= t}` and `{v > t}`. Returns 0 for an empty or constant input.
pub fn otsu_level(values: &[u8]) -> u8 {
    let mut hist = [0u64; 256];
    for &v in values {
        hist[usize::from(v)] += 1;
    }
    let total = values.len() as f64;
    if total == 0.0 {
        return 0;
    }
    let sum_all: f64 = hist
        .iter()
        .enumerate()
        .map(|(i, &c)| i as f64 * c as f64)
        .sum();
    let (mut w0, mut sum0) = (0.0f64, 0.0f64);
    let (mut best, mut best_t) = (-1.0f64, 0u8);
    for (t, &c) in hist.iter().enumerate() {
        w0 += c as f64;
        sum0 += t as f64 * c as f64;
        let w1 = total - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let m0 = sum0 / w0;
        let m1 = (sum_all - sum0) / w1;
        let between = w0 * w1 * (m0 - m1) * (m0 - m1);
        if between > best {
            best = between;
            best_t = t as u8;
        }
    }
    best_t
}

/// Converts packed RGB (3 bytes per pixel) to grey (ITU-R BT.601 luma, integer weights) into
/// `out`, which keeps its capacity, and views it.
pub fn rgb_to_gray<'a>(
    rgb: &[u8],
    width: usize,
    height: usize,
    out: &'a mut Vec<u8>,
) -> Result<GrayView<'a>, ImageError> {
    to_gray::<3>(rgb, width, height, out)
}

/// Converts packed RGBA (4 bytes per pixel; alpha ignored) to grey into `out` and views it.
pub fn rgba_to_gray<'a>(
    rgba: &[u8],
    width: usize,
    height: usize,
    out: &'a mut Vec<u8>,
) -> Result<GrayView<'a>, ImageError> {
    to_gray::<4>(rgba, width, height, out)
}

fn to_gray<'a, const C: usize>(
    src: &[u8],
    width: usize,
    height: usize,
    out: &'a mut Vec<u8>,
) -> Result<GrayView<'a>, ImageError> {
    // Validate the shape first (an empty `out` would be reported as too short otherwise).
    let n = width.saturating_mul(height);
    if width == 0 || height == 0 || width > GrayView::MAX_SIDE || height > GrayView::MAX_SIDE {
        // Let GrayView produce the right error variant.
        return GrayView::new(&[], width, height);
    }
    if src.len() < n * C {
        return Err(ImageError::BufferTooShort {
            len: src.len() / C,
            width,
            height,
            stride: width,
        });
    }
    out.clear();
    out.extend(src[..n * C].chunks_exact(C).map(|p| {
        // 0.299 R + 0.587 G + 0.114 B in 16-bit fixed point.
        ((19595 * u32::from(p[0]) + 38470 * u32::from(p[1]) + 7471 * u32::from(p[2]) + 32768) >> 16)
            as u8
    }));
    GrayView::new(out, width, height)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binarize(data: &[u8], w: usize, h: usize, t: Threshold) -> Vec<u8> {
        let img = GrayView::new(data, w, h).unwrap();
        let mut b = Binarizer::new();
        let mut out = Vec::new();
        b.binarize(&img, t, &mut out);
        out
    }

    /// The scalar definition of the 3x3 box mean and of the line-preserving level, pixel by
    /// pixel with replicated borders: what the row kernel (`levels_rows`) must reproduce exactly.
    fn reference_box3(img: &[u8], w: usize, h: usize) -> (Vec<u8>, Vec<u8>) {
        let at = |x: isize, y: isize| {
            let x = x.clamp(0, w as isize - 1) as usize;
            let y = y.clamp(0, h as isize - 1) as usize;
            u32::from(img[y * w + x])
        };
        let (mut smooth, mut fine) = (vec![0u8; w * h], vec![0u8; w * h]);
        for y in 0..h as isize {
            for x in 0..w as isize {
                let s: u32 = (-1..=1)
                    .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
                    .map(|(dx, dy)| at(x + dx, y + dy))
                    .sum();
                let o = ((s * 7282) >> 16) as u8;
                let horiz = at(x - 1, y) + at(x, y) + at(x + 1, y);
                let vert = at(x, y - 1) + at(x, y) + at(x, y + 1);
                let least = horiz.min(vert);
                let i = y as usize * w + x as usize;
                smooth[i] = o;
                fine[i] = if 3 * least + 9 * LINE_STEP < s {
                    (least / 3) as u8
                } else {
                    o
                };
            }
        }
        (smooth, fine)
    }

    proptest::proptest! {
        #[test]
        fn box3_matches_the_scalar_definition(
            w in 1usize..40,
            h in 1usize..12,
            seed in proptest::prelude::any::<u64>(),
            two_level in proptest::prelude::any::<bool>(),
        ) {
            // Random bytes, or two levels (so that the line rule fires often).
            let img = crate::test_bytes(seed, w * h, |_, state| {
                if two_level { if state & 1 == 0 { 20 } else { 230 } } else { state as u8 }
            });
            let view = GrayView::new(&img, w, h).unwrap();
            // The row kernel the binarizer runs (levels into the output, means kept), twice
            // on one scratch with a larger frame in between, so stale contents would show.
            let mut band = Band::default();
            let big = vec![255u8; 64 * 16];
            let (mut smooth, mut fine) = (vec![0u8; 64 * 16], vec![0u8; 64 * 16]);
            let big_view = GrayView::new(&big, 64, 16).unwrap();
            levels_rows(&big_view, 0, &mut fine, Some(&mut smooth), &mut band.hsum);
            let (mut smooth, mut fine) = (vec![0u8; w * h], vec![0u8; w * h]);
            levels_rows(&view, 0, &mut fine, Some(&mut smooth), &mut band.hsum);
            let (smooth_ref, fine_ref) = reference_box3(&img, w, h);
            proptest::prop_assert_eq!(&smooth, &smooth_ref);
            proptest::prop_assert_eq!(&fine, &fine_ref);
            // Started part-way down (as a band of binarize_parallel is).
            if h > 2 {
                let y0 = h / 2;
                let mut part = vec![0u8; (h - y0) * w];
                levels_rows(&view, y0, &mut part, None, &mut band.hsum);
                proptest::prop_assert_eq!(&part[..], &fine_ref[y0 * w..]);
            }
            // Through binarize with Otsu, which keeps the means.
            let mut b = Binarizer::new();
            let mut out = Vec::new();
            b.binarize(&view, Threshold::Otsu, &mut out);
            proptest::prop_assert_eq!(b.smoothed(), &smooth_ref[..]);
            proptest::prop_assert_eq!(out.len(), w * h);
        }
    }

    proptest::proptest! {
        #[test]
        fn parallel_bands_give_the_single_threaded_output(
            w in 1usize..90,
            h in 1usize..90,
            bands in 2usize..5,
            tile in 2usize..12,
            otsu in proptest::prelude::any::<bool>(),
            seed in proptest::prelude::any::<u64>(),
        ) {
            let img = crate::test_bytes(seed, w * h, |i, state| {
                // Blocks of two levels with noise, so that both cuts fire.
                let base = if (i % w / 7 + i / w / 5) % 2 == 0 { 40 } else { 210 };
                (base + (state % 16) as u32) as u8
            });
            let t = if otsu {
                Threshold::Otsu
            } else {
                Threshold::Adaptive { tile_size: tile, min_contrast: 30 }
            };
            let view = GrayView::new(&img, w, h).unwrap();
            let serial = binarize(&img, w, h, t);
            let mut b = Binarizer::new();
            let mut out = Vec::new();
            b.binarize_parallel(&view, t, &mut out, bands);
            proptest::prop_assert_eq!(&out, &serial);
            // Reused, on the same frame, after a single-threaded call.
            b.binarize(&view, t, &mut out);
            b.binarize_parallel(&view, t, &mut out, bands);
            proptest::prop_assert_eq!(&out, &serial);
        }
    }

    proptest::proptest! {
        /// The compilation chosen at run time (AVX2 on a CPU that has it, see
        /// `extremes_and_cut`) gives the bits of the baseline one, called directly here. On a
        /// CPU without AVX2 both are the baseline and this checks nothing more.
        #[test]
        fn avx2_and_baseline_binarizations_agree(
            w in 1usize..200,
            h in 1usize..40,
            tile in 2usize..12,
            min_contrast in 0u8..60,
            seed in proptest::prelude::any::<u64>(),
        ) {
            let img = crate::test_bytes(seed, w * h, |i, state| {
                // Blocks of two levels with noise and thin lines, so that every test
                // of the cut fires.
                let base = if (i % w / 9 + i / w / 6) % 2 == 0 { 30 } else { 220 };
                let line = if i % w % 13 == 0 { 0 } else { base };
                (line + (state % 24) as u32) as u8
            });
            let view = GrayView::new(&img, w, h).unwrap();
            let t = Threshold::Adaptive { tile_size: tile, min_contrast };
            let dispatched = binarize(&img, w, h, t);
            let side = t.tile_side();
            let tiles = Tiles {
                side,
                tx: w.div_ceil(side),
                ty: h.div_ceil(side),
                min_contrast,
                width: w,
                height: h,
            };
            let mut baseline = vec![0u8; w * h];
            extremes_and_cut_body(&view, &mut baseline, &tiles, (0, tiles.ty), &mut Band::default());
            proptest::prop_assert_eq!(&dispatched, &baseline);
        }
    }

    /// The whole binarization rule, written out pixel by pixel from the module's
    /// documentation (not from the row-wise code): the 3x3 box mean `m = (s * 7282) >> 16` of
    /// the nine-pixel sum `s` (replicated borders); the line-preserving level (`least / 3`
    /// where the darker of the 1x3 and 3x1 sums `least` satisfies `3 least + 9 LINE_STEP <
    /// s`, else `m`); for [`Threshold::Adaptive`], per tile (side clamped to 2..=64, the last
    /// tiles of a row or column cut short) the minimum and maximum of `m` over its 3x3 tile
    /// neighbourhood, the threshold their rounded-up midpoint, or nothing dark where their
    /// difference is below `min_contrast`, and dark where the level is below the threshold;
    /// for [`Threshold::Otsu`], dark where the level is at most Otsu's level of all `m`.
    fn reference_binarize(img: &[u8], w: usize, h: usize, t: Threshold) -> Vec<u8> {
        let at = |x: isize, y: isize| {
            let x = x.clamp(0, w as isize - 1) as usize;
            let y = y.clamp(0, h as isize - 1) as usize;
            u32::from(img[y * w + x])
        };
        let mut mean = vec![0u8; w * h];
        let mut level = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let (xi, yi) = (x as isize, y as isize);
                let mut s = 0;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        s += at(xi + dx, yi + dy);
                    }
                }
                let horiz = at(xi - 1, yi) + at(xi, yi) + at(xi + 1, yi);
                let vert = at(xi, yi - 1) + at(xi, yi) + at(xi, yi + 1);
                let least = horiz.min(vert);
                let m = (s * 7282) >> 16;
                mean[y * w + x] = m as u8;
                level[y * w + x] = if 3 * least + 9 * LINE_STEP < s {
                    (least / 3) as u8
                } else {
                    m as u8
                };
            }
        }
        let (tile, min_contrast) = match t {
            Threshold::Otsu => {
                let cut = otsu_level(&mean);
                return level.iter().map(|&v| u8::from(v <= cut)).collect();
            }
            Threshold::Adaptive {
                tile_size,
                min_contrast,
            } => (tile_size.clamp(2, 64), min_contrast),
        };
        let (tx, ty) = (w.div_ceil(tile), h.div_ceil(tile));
        let mut out = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let (i, j) = (x / tile, y / tile);
                // Pixels of the tiles i-1..=i+1, j-1..=j+1 that exist.
                let x0 = i.saturating_sub(1) * tile;
                let x1 = ((i + 2).min(tx) * tile).min(w);
                let y0 = j.saturating_sub(1) * tile;
                let y1 = ((j + 2).min(ty) * tile).min(h);
                let (mut lo, mut hi) = (255u8, 0u8);
                for yy in y0..y1 {
                    for xx in x0..x1 {
                        lo = lo.min(mean[yy * w + xx]);
                        hi = hi.max(mean[yy * w + xx]);
                    }
                }
                if hi - lo >= min_contrast {
                    let thr = (u32::from(lo) + u32::from(hi)).div_ceil(2);
                    out[y * w + x] = u8::from(u32::from(level[y * w + x]) < thr);
                }
            }
        }
        out
    }

    /// A test frame of `w x h` from `seed`: random bytes (kind 0), two levels (1, so that
    /// the line rule fires often), blocks of two levels with noise (2), a smooth ramp with
    /// noise (3, low contrast, so that `min_contrast` matters).
    fn test_frame(w: usize, h: usize, kind: u8, seed: u64) -> Vec<u8> {
        let mut state = seed | 1;
        (0..w * h)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let (x, y) = (i % w, i / w);
                match kind % 4 {
                    0 => state as u8,
                    1 => {
                        if state & 1 == 0 {
                            20
                        } else {
                            230
                        }
                    }
                    2 => {
                        let base = if (x / 5 + y / 3) % 2 == 0 { 40 } else { 200 };
                        (base + (state % 24) as u32) as u8
                    }
                    _ => (x * 3 + y + (state % 8) as usize).min(255) as u8,
                }
            })
            .collect()
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(512))]
        #[test]
        fn binarize_matches_the_pixel_by_pixel_rule(
            w in 1usize..80,
            h in 1usize..48,
            kind in 0u8..4,
            tile in 0usize..70,
            min_contrast in proptest::prelude::any::<u8>(),
            otsu in proptest::prelude::any::<bool>(),
            pad in 0usize..3,
            bands in 1usize..5,
            seed in proptest::prelude::any::<u64>(),
        ) {
            let img = test_frame(w, h, kind, seed);
            let t = if otsu {
                Threshold::Otsu
            } else {
                Threshold::Adaptive { tile_size: tile, min_contrast }
            };
            let expected = reference_binarize(&img, w, h, t);
            // The same frame inside a wider buffer (stride `w + pad`), with garbage between
            // rows that must not be read.
            let stride = w + pad;
            let mut padded = vec![0u8; stride * h];
            for (y, row) in img.chunks_exact(w).enumerate() {
                padded[y * stride..y * stride + w].copy_from_slice(row);
                padded[y * stride + w..(y + 1) * stride].fill(if y % 2 == 0 { 0 } else { 255 });
            }
            let view = GrayView::with_stride(&padded, w, h, stride).unwrap();
            let mut b = Binarizer::new();
            // Filled with a different frame first, so that stale buffer contents would show.
            let other = test_frame(70, 40, kind + 1, !seed);
            let mut out = vec![7u8; 3];
            b.binarize(&GrayView::new(&other, 70, 40).unwrap(), t, &mut out);
            b.binarize(&view, t, &mut out);
            proptest::prop_assert_eq!(&out, &expected);
            b.binarize_parallel(&view, t, &mut out, bands);
            proptest::prop_assert_eq!(&out, &expected);
        }
    }

    #[test]
    fn reference_rule_sees_dark_lines_and_flat_areas() {
        // The reference itself must behave as documented, or the comparison above proves
        // little: a flat frame has nothing dark, a dark two-pixel line on light is dark
        // (on the line rule: the 3x3 mean alone would mix in the light surround).
        let (w, h) = (24usize, 16usize);
        let flat = vec![128u8; w * h];
        assert!(
            reference_binarize(&flat, w, h, Threshold::default())
                .iter()
                .all(|&v| v == 0)
        );
        let mut lined = vec![220u8; w * h];
        for y in 0..h {
            lined[y * w + 11] = 10;
            lined[y * w + 12] = 10;
        }
        let out = reference_binarize(&lined, w, h, Threshold::default());
        assert!((0..h).all(|y| out[y * w + 11] == DARK && out[y * w + 12] == DARK));
        assert!((0..h).all(|y| out[y * w + 3] == 0 && out[y * w + 20] == 0));
    }

    #[test]
    fn scaled_thresholds_give_the_same_tests() {
        // Every nine-pixel sum and 3-sum a frame can give, against every threshold: the cut's
        // scaled tests (`cut_run`) decide as the level's definition does.
        for t in 0..=255u8 {
            let (st, lt) = (SumOrLine::Sum.scale(t), SumOrLine::Line.scale(t));
            for s in 0..=9 * 255u16 {
                assert_eq!(box_mean(s) < t, (s as i16) < st, "sum {s}, threshold {t}");
            }
            for l in 0..=3 * 255u16 {
                assert_eq!(
                    ((l / 3) as u8) < t,
                    (l as i16) < lt,
                    "3-sum {l}, threshold {t}"
                );
            }
        }
    }

    #[test]
    fn dark_square_on_gradient_is_dark_everywhere() {
        // A 4:1 lighting gradient left to right with a dark square in each half.
        let (w, h) = (320usize, 48usize);
        let mut img = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let light = 1.0 - 0.75 * x as f64 / (w - 1) as f64;
                let inside =
                    (8..24).contains(&y) && ((8..24).contains(&x) || (280..296).contains(&x));
                let albedo = if inside { 0.1 } else { 0.9 };
                img[y * w + x] = (255.0 * light * albedo) as u8;
            }
        }
        let out = binarize(&img, w, h, Threshold::default());
        for (x, y) in [(16, 16), (288, 16), (10, 10), (294, 22)] {
            assert_eq!(out[y * w + x], DARK, "({x},{y}) should be dark");
        }
        for (x, y) in [(40, 16), (160, 40), (300, 40), (4, 4)] {
            assert_eq!(out[y * w + x], 0, "({x},{y}) should be light");
        }
    }

    #[test]
    fn flat_frame_has_no_dark_pixel() {
        let img = vec![90u8; 50 * 30];
        assert!(
            binarize(&img, 50, 30, Threshold::default())
                .iter()
                .all(|&v| v == 0)
        );
    }

    #[test]
    fn otsu_splits_two_levels() {
        let mut img = vec![200u8; 40 * 40];
        for v in img.iter_mut().take(400) {
            *v = 30;
        }
        assert!((30..200).contains(&otsu_level(&img)));
        let out = binarize(&img, 40, 40, Threshold::Otsu);
        assert_eq!(out[0], DARK);
        assert_eq!(out[40 * 39], 0);
    }

    #[test]
    fn tiny_images_do_not_panic() {
        for (w, h) in [(1, 1), (1, 5), (5, 1), (2, 2), (3, 1)] {
            let img = vec![7u8; w * h];
            assert_eq!(binarize(&img, w, h, Threshold::default()).len(), w * h);
            assert_eq!(binarize(&img, w, h, Threshold::Otsu).len(), w * h);
        }
    }

    #[test]
    fn rgb_conversion() {
        let rgb = [255, 255, 255, 0, 0, 0, 255, 0, 0];
        let mut out = Vec::new();
        let g = rgb_to_gray(&rgb, 3, 1, &mut out).unwrap();
        assert_eq!(g.row(0), &[255, 0, 76]);
        let rgba = [255, 255, 255, 9, 0, 0, 0, 9];
        let g = rgba_to_gray(&rgba, 2, 1, &mut out).unwrap();
        assert_eq!(g.row(0), &[255, 0]);
        assert!(matches!(
            rgb_to_gray(&rgb, 4, 1, &mut out),
            Err(ImageError::BufferTooShort { .. })
        ));
        assert!(matches!(
            rgb_to_gray(&rgb, 0, 1, &mut out),
            Err(ImageError::Empty { .. })
        ));
    }
}
