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
    hsum: Vec<u16>,
    tile_min: Vec<u8>,
    tile_max: Vec<u8>,
    tile_thr: Vec<u8>,
    row_min: Vec<u8>,
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
        let (w, h) = (img.width(), img.height());
        self.box3(img);
        // Both cuts below write every byte: resize only.
        out.resize(w * h, 0);
        match threshold {
            Threshold::Adaptive {
                tile_size,
                min_contrast,
            } => self.adaptive(w, h, tile_size.clamp(2, 64), min_contrast, out),
            Threshold::Otsu => {
                let t = otsu_level(&self.smooth);
                for (o, &s) in out.iter_mut().zip(&self.fine) {
                    *o = u8::from(s <= t);
                }
            }
        }
    }

    /// The smoothed frame of the last call (3x3 box filter), row-major, `width` per row.
    pub fn smoothed(&self) -> &[u8] {
        &self.smooth
    }

    /// 3x3 box filter with replicated borders into `self.smooth`, and the line-preserving
    /// level into `self.fine`.
    ///
    /// Every row loop runs over slices of one length in 16-bit arithmetic (no sum exceeds
    /// 9 * 255), so it vectorises; the output is identical to the scalar definition (a test
    /// checks it against that).
    fn box3(&mut self, img: &GrayView<'_>) {
        let (w, h) = (img.width(), img.height());
        // Every byte of both buffers is written below: resize only (no clear and refill).
        self.smooth.resize(w * h, 0);
        self.fine.resize(w * h, 0);
        // Three rows of horizontal 3-sums, as a ring.
        self.hsum.resize(3 * w, 0);
        // hsum slot k holds the horizontal sums of row (y - 1 + k) (clamped).
        let (s0, rest) = self.hsum.split_at_mut(w);
        let (s1, s2) = rest.split_at_mut(w);
        let mut slots = [s0, s1, s2];
        hrow(img.row(0), slots[0]);
        hrow(img.row(0), slots[1]);
        hrow(img.row(1.min(h - 1)), slots[2]);
        for (y, (out, fine)) in self
            .smooth
            .chunks_exact_mut(w)
            .zip(self.fine.chunks_exact_mut(w))
            .enumerate()
        {
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
            if y + 1 < h {
                slots.rotate_left(1);
                hrow(img.row((y + 2).min(h - 1)), slots[2]);
            }
        }
    }

    fn adaptive(&mut self, w: usize, h: usize, tile: usize, min_contrast: u8, out: &mut [u8]) {
        let tx = w.div_ceil(tile);
        let ty = h.div_ceil(tile);
        self.tile_min.clear();
        self.tile_min.resize(tx * ty, u8::MAX);
        self.tile_max.clear();
        self.tile_max.resize(tx * ty, 0);
        // Per tile row: element-wise min/max over its rows (vectorises), then one reduction
        // per tile.
        self.row_min.clear();
        self.row_min.resize(w, 0);
        self.row_max.clear();
        self.row_max.resize(w, 0);
        for (j, band) in self.smooth.chunks(tile * w).enumerate() {
            let mut rows = band.chunks_exact(w);
            if let Some(first) = rows.next() {
                self.row_min.copy_from_slice(first);
                self.row_max.copy_from_slice(first);
            }
            for row in rows {
                for ((mn, mx), &v) in self
                    .row_min
                    .iter_mut()
                    .zip(self.row_max.iter_mut())
                    .zip(row)
                {
                    *mn = (*mn).min(v);
                    *mx = (*mx).max(v);
                }
            }
            let mins = &mut self.tile_min[j * tx..(j + 1) * tx];
            let maxs = &mut self.tile_max[j * tx..(j + 1) * tx];
            for (((cmin, cmax), mn), mx) in self
                .row_min
                .chunks(tile)
                .zip(self.row_max.chunks(tile))
                .zip(mins)
                .zip(maxs)
            {
                *mn = cmin.iter().copied().fold(u8::MAX, u8::min);
                *mx = cmax.iter().copied().fold(0, u8::max);
            }
        }
        self.tile_thr.clear();
        self.tile_thr.resize(tx * ty, 0);
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
                        lo = lo.min(self.tile_min[k]);
                        hi = hi.max(self.tile_max[k]);
                    }
                }
                // Threshold 0 means "nothing here is dark" (no value is below 0).
                self.tile_thr[j * tx + i] = if hi.saturating_sub(lo) < min_contrast {
                    0
                } else {
                    ((u16::from(lo) + u16::from(hi)).div_ceil(2)) as u8
                };
            }
        }
        // Per tile row: expand the thresholds to one per pixel, then compare whole rows.
        for (j, (band, oband)) in self
            .fine
            .chunks(tile * w)
            .zip(out.chunks_mut(tile * w))
            .enumerate()
        {
            let thr = &self.tile_thr[j * tx..(j + 1) * tx];
            for (chunk, &t) in self.row_min.chunks_mut(tile).zip(thr) {
                chunk.fill(t);
            }
            for (row, orow) in band.chunks_exact(w).zip(oband.chunks_exact_mut(w)) {
                for ((o, &v), &t) in orow.iter_mut().zip(row).zip(&self.row_min) {
                    *o = u8::from(v < t);
                }
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
