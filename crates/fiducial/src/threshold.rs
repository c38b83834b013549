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
#[derive(Debug, Default, Clone)]
pub struct Binarizer {
    smooth: Vec<u8>,
    fine: Vec<u8>,
    tile_min: Vec<u8>,
    tile_max: Vec<u8>,
    tile_thr: Vec<u8>,
    /// Scratch rows of each band of rows (one band unless [`Binarizer::binarize_parallel`]).
    bands: Vec<Band>,
}

/// One band's work in phase 1 of [`Binarizer::binarize_parallel`]: its index, its rows of
/// the smoothed and line-preserving frames, its tile rows of minima and maxima, its scratch.
type SmoothBand<'a> = (
    usize,
    (
        (((&'a mut [u8], &'a mut [u8]), &'a mut [u8]), &'a mut [u8]),
        &'a mut Band,
    ),
);

/// One band's work in phase 3: its rows of the line-preserving frame and of the output, its
/// tile rows of thresholds, its scratch.
type CutBand<'a> = ((&'a [u8], &'a mut [u8]), (&'a [u8], &'a mut Band));

/// The scratch rows one band of rows needs.
#[derive(Debug, Default, Clone)]
struct Band {
    /// Three rows of horizontal 3-sums (a ring).
    hsum: Vec<u16>,
    /// Element-wise minimum of a tile row's rows, later its thresholds expanded per pixel.
    row_min: Vec<u8>,
    /// Element-wise maximum of a tile row's rows.
    row_max: Vec<u8>,
}

impl Binarizer {
    /// An empty binarizer; buffers grow on the first frame.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes the binary image of `img` into `out` (`width * height` bytes, row-major,
    /// [`DARK`] for dark pixels, 0 for light). `out` keeps its capacity between calls.
    pub fn binarize(&mut self, img: &GrayView<'_>, threshold: Threshold, out: &mut Vec<u8>) {
        self.run(img, threshold, out, 1);
    }

    /// [`Binarizer::binarize`] on up to `bands` threads of the current rayon pool (with the
    /// crate feature `parallel`; without it the bands run one after the other): the frame
    /// is cut into horizontal bands of whole tile rows, each band is smoothed and reduced to
    /// tile minima and maxima on its own thread, the tile thresholds are computed once, and
    /// each band is then cut on its own thread. Every stage reads the same pixels as the
    /// single-threaded pass, so the output is identical to [`Binarizer::binarize`]'s.
    pub fn binarize_parallel(
        &mut self,
        img: &GrayView<'_>,
        threshold: Threshold,
        out: &mut Vec<u8>,
        bands: usize,
    ) {
        self.run(img, threshold, out, bands.max(1));
    }

    fn run(&mut self, img: &GrayView<'_>, threshold: Threshold, out: &mut Vec<u8>, bands: usize) {
        let (w, h) = (img.width(), img.height());
        // Every byte of these is written below: resize only (no clear and refill).
        self.smooth.resize(w * h, 0);
        self.fine.resize(w * h, 0);
        out.resize(w * h, 0);
        let (tile, min_contrast) = match threshold {
            Threshold::Adaptive {
                tile_size,
                min_contrast,
            } => (tile_size.clamp(2, 64), Some(min_contrast)),
            // Otsu has no tiles; bands are still cut at multiples of 8 rows.
            Threshold::Otsu => (8, None),
        };
        let (tx, ty) = (w.div_ceil(tile), h.div_ceil(tile));
        let band_tiles = ty.div_ceil(bands.clamp(1, ty));
        let band_rows = band_tiles * tile;
        let count = h.div_ceil(band_rows);
        if self.bands.len() < count {
            self.bands.resize_with(count, Band::default);
        }
        self.tile_min.resize(tx * ty, 0);
        self.tile_max.resize(tx * ty, 0);
        // Phase 1: smoothing, and the tile minima and maxima, per band.
        let adaptive = min_contrast.is_some();
        let smooth_band = |(b, ((((sm, fi), mn), mx), band)): SmoothBand<'_>| {
            box3_rows(img, b * band_rows, sm, fi, &mut band.hsum);
            if adaptive {
                tile_extremes(sm, w, tile, tx, band, mn, mx);
            }
        };
        if count == 1 {
            smooth_band((
                0,
                (
                    (
                        (
                            (&mut self.smooth[..], &mut self.fine[..]),
                            &mut self.tile_min[..],
                        ),
                        &mut self.tile_max[..],
                    ),
                    &mut self.bands[0],
                ),
            ));
        } else {
            #[cfg(feature = "parallel")]
            {
                use rayon::prelude::*;
                self.smooth
                    .par_chunks_mut(band_rows * w)
                    .zip(self.fine.par_chunks_mut(band_rows * w))
                    .zip(self.tile_min.par_chunks_mut(band_tiles * tx))
                    .zip(self.tile_max.par_chunks_mut(band_tiles * tx))
                    .zip(self.bands.par_iter_mut())
                    .enumerate()
                    .for_each(smooth_band);
            }
            #[cfg(not(feature = "parallel"))]
            self.smooth
                .chunks_mut(band_rows * w)
                .zip(self.fine.chunks_mut(band_rows * w))
                .zip(self.tile_min.chunks_mut(band_tiles * tx))
                .zip(self.tile_max.chunks_mut(band_tiles * tx))
                .zip(self.bands.iter_mut())
                .enumerate()
                .for_each(smooth_band);
        }
        let Some(min_contrast) = min_contrast else {
            let t = otsu_level(&self.smooth);
            for (o, &s) in out.iter_mut().zip(&self.fine) {
                *o = u8::from(s <= t);
            }
            return;
        };
        // Phase 2: one threshold per tile, from its 3x3 tile neighbourhood.
        tile_thresholds(
            &self.tile_min,
            &self.tile_max,
            tx,
            ty,
            min_contrast,
            &mut self.tile_thr,
        );
        // Phase 3: the cut, per band.
        let cut_band = |((fi, o), (thr, band)): CutBand<'_>| {
            cut_rows(fi, o, thr, w, tile, &mut band.row_min);
        };
        if count == 1 {
            cut_band((
                (&self.fine[..], &mut out[..]),
                (&self.tile_thr[..], &mut self.bands[0]),
            ));
        } else {
            #[cfg(feature = "parallel")]
            {
                use rayon::prelude::*;
                self.fine
                    .par_chunks(band_rows * w)
                    .zip(out.par_chunks_mut(band_rows * w))
                    .zip(
                        self.tile_thr
                            .par_chunks(band_tiles * tx)
                            .zip(self.bands.par_iter_mut()),
                    )
                    .for_each(cut_band);
            }
            #[cfg(not(feature = "parallel"))]
            self.fine
                .chunks(band_rows * w)
                .zip(out.chunks_mut(band_rows * w))
                .zip(
                    self.tile_thr
                        .chunks(band_tiles * tx)
                        .zip(self.bands.iter_mut()),
                )
                .for_each(cut_band);
        }
    }

    /// The smoothed frame of the last call (3x3 box filter), row-major, `width` per row.
    pub fn smoothed(&self) -> &[u8] {
        &self.smooth
    }
}

/// 3x3 box filter with replicated borders of the rows `y0 ..` of `img` that `smooth` holds
/// (whole rows) into `smooth`, and the line-preserving level into `fine`.
///
/// Every row loop runs over slices of one length in 16-bit arithmetic (no sum exceeds
/// 9 * 255), so it vectorises; the output is identical to the scalar definition (a test
/// checks it against that).
fn box3_rows(
    img: &GrayView<'_>,
    y0: usize,
    smooth: &mut [u8],
    fine: &mut [u8],
    hsum: &mut Vec<u16>,
) {
    let (w, h) = (img.width(), img.height());
    let rows = smooth.len() / w;
    // Three rows of horizontal 3-sums, as a ring.
    hsum.resize(3 * w, 0);
    // hsum slot k holds the horizontal sums of row (y - 1 + k) (clamped).
    let (s0, rest) = hsum.split_at_mut(w);
    let (s1, s2) = rest.split_at_mut(w);
    let mut slots = [s0, s1, s2];
    hrow(img.row(y0.saturating_sub(1)), slots[0]);
    hrow(img.row(y0), slots[1]);
    hrow(img.row((y0 + 1).min(h - 1)), slots[2]);
    for (i, (out, fine)) in smooth
        .chunks_exact_mut(w)
        .zip(fine.chunks_exact_mut(w))
        .enumerate()
    {
        let y = y0 + i;
        let (up, mid, down) = (
            img.row(y.saturating_sub(1)),
            img.row(y),
            img.row((y + 1).min(h - 1)),
        );
        box_row(
            [&*slots[0], &*slots[1], &*slots[2]],
            [up, mid, down],
            out,
            fine,
        );
        if i + 1 < rows {
            slots.rotate_left(1);
            hrow(img.row((y + 2).min(h - 1)), slots[2]);
        }
    }
}

/// Minimum and maximum of each tile of the band `smooth` (whole tile rows, `w` per row) into
/// `mins` and `maxs` (`tx` per tile row): per tile row, element-wise min/max over its rows
/// (vectorises), then one reduction per tile.
fn tile_extremes(
    smooth: &[u8],
    w: usize,
    tile: usize,
    tx: usize,
    band: &mut Band,
    mins: &mut [u8],
    maxs: &mut [u8],
) {
    band.row_min.resize(w, 0);
    band.row_max.resize(w, 0);
    for ((rows, mins), maxs) in smooth
        .chunks(tile * w)
        .zip(mins.chunks_mut(tx))
        .zip(maxs.chunks_mut(tx))
    {
        let mut rows = rows.chunks_exact(w);
        if let Some(first) = rows.next() {
            band.row_min.copy_from_slice(first);
            band.row_max.copy_from_slice(first);
        }
        for row in rows {
            for ((mn, mx), &v) in band
                .row_min
                .iter_mut()
                .zip(band.row_max.iter_mut())
                .zip(row)
            {
                *mn = (*mn).min(v);
                *mx = (*mx).max(v);
            }
        }
        for (((cmin, cmax), mn), mx) in band
            .row_min
            .chunks(tile)
            .zip(band.row_max.chunks(tile))
            .zip(mins)
            .zip(maxs)
        {
            *mn = cmin.iter().copied().fold(u8::MAX, u8::min);
            *mx = cmax.iter().copied().fold(0, u8::max);
        }
    }
}

/// Each tile's threshold: the midpoint of the minimum and maximum over its 3x3 tile
/// neighbourhood, or 0 ("nothing here is dark") where their difference is below
/// `min_contrast`.
fn tile_thresholds(
    tile_min: &[u8],
    tile_max: &[u8],
    tx: usize,
    ty: usize,
    min_contrast: u8,
    thr: &mut Vec<u8>,
) {
    thr.resize(tx * ty, 0);
    for j in 0..ty {
        let j0 = j.saturating_sub(1);
        let j1 = (j + 1).min(ty - 1);
        for i in 0..tx {
            let i0 = i.saturating_sub(1);
            let i1 = (i + 1).min(tx - 1);
            let mut lo = u8::MAX;
            let mut hi = 0u8;
            for jj in j0..=j1 {
                let base = jj * tx;
                for k in base + i0..=base + i1 {
                    lo = lo.min(tile_min[k]);
                    hi = hi.max(tile_max[k]);
                }
            }
            thr[j * tx + i] = if hi.saturating_sub(lo) < min_contrast {
                0
            } else {
                ((u16::from(lo) + u16::from(hi)).div_ceil(2)) as u8
            };
        }
    }
}

/// The cut of the band `fine` into `out`: per tile row, the thresholds `thr` (`w / tile`
/// rounded up per tile row) expanded to one per pixel in `expanded`, then whole rows compared.
fn cut_rows(
    fine: &[u8],
    out: &mut [u8],
    thr: &[u8],
    w: usize,
    tile: usize,
    expanded: &mut Vec<u8>,
) {
    let tx = w.div_ceil(tile);
    expanded.resize(w, 0);
    for ((band, oband), thr) in fine
        .chunks(tile * w)
        .zip(out.chunks_mut(tile * w))
        .zip(thr.chunks(tx))
    {
        for (chunk, &t) in expanded.chunks_mut(tile).zip(thr) {
            chunk.fill(t);
        }
        for (row, orow) in band.chunks_exact(w).zip(oband.chunks_exact_mut(w)) {
            for ((o, &v), &t) in orow.iter_mut().zip(row).zip(expanded.iter()) {
                *o = u8::from(v < t);
            }
        }
    }
}

/// Horizontal 3-sums of `src` with the end pixels replicated, into `dst` (same length).
#[inline]
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

/// One row of the 3x3 box mean (`out`) and of the line-preserving level (`fine`) from the
/// horizontal sums of the rows above, at and below (`hs`) and those rows' pixels (`px`).
#[inline]
fn box_row(hs: [&[u16]; 3], px: [&[u8]; 3], out: &mut [u8], fine: &mut [u8]) {
    let w = out.len();
    let fine = &mut fine[..w];
    let (a, b, c) = (&hs[0][..w], &hs[1][..w], &hs[2][..w]);
    let (u, m, d) = (&px[0][..w], &px[1][..w], &px[2][..w]);
    for i in 0..w {
        let s = a[i] + b[i] + c[i];
        // s / 9 without a division (a 16-bit multiply-high): 7282 / 65536 = 0.11111.
        let o = ((u32::from(s) * 7282) >> 16) as u16;
        // The darkest of the 3x3 box and the 3x1 and 1x3 ones (sums times 3, so that all
        // three compare on one scale): a dark line two pixels wide along either axis keeps
        // its level in the 1x3 box along it, where the 3x3 box would mix in its light
        // surround (see `Binarizer::binarize`). All terms stay below 2^16.
        let vert = u16::from(u[i]) + u16::from(m[i]) + u16::from(d[i]);
        let least = b[i].min(vert);
        let line = 3 * least + LINE_STEP_9 < s;
        out[i] = o as u8;
        fine[i] = if line { (least / 3) as u8 } else { o as u8 };
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
    /// pixel with replicated borders: what `Binarizer::box3` must reproduce exactly.
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
            let mut state = seed | 1;
            let img: Vec<u8> = (0..w * h)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    if two_level { if state & 1 == 0 { 20 } else { 230 } } else { state as u8 }
                })
                .collect();
            let view = GrayView::new(&img, w, h).unwrap();
            let mut b = Binarizer::new();
            // Twice, with a larger frame in between, so stale buffer contents would show.
            let big = vec![255u8; 64 * 16];
            let mut out = Vec::new();
            b.binarize(&view, Threshold::default(), &mut out);
            b.binarize(&GrayView::new(&big, 64, 16).unwrap(), Threshold::default(), &mut out);
            b.binarize(&view, Threshold::default(), &mut out);
            let (smooth, fine) = reference_box3(&img, w, h);
            proptest::prop_assert_eq!(&b.smooth, &smooth);
            proptest::prop_assert_eq!(&b.fine, &fine);
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
            let mut state = seed | 1;
            let img: Vec<u8> = (0..w * h)
                .map(|i| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    // Blocks of two levels with noise, so that both cuts fire.
                    let base = if (i % w / 7 + i / w / 5) % 2 == 0 { 40 } else { 210 };
                    (base + (state % 16) as u32) as u8
                })
                .collect();
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
