//! A second look at dark components that gave no quadrilateral: re-cut them at a darker
//! threshold, so that a marker border merged with its surroundings through a thin bridge
//! becomes a component of its own (issue #13, real frames).
//!
//! A marker lying almost flat, seen at a grazing angle, has a white margin only a pixel or
//! two tall on its far side. Blur pulls that margin below the midpoint threshold, and the
//! black border's component joins the grey table, a shadow or a neighbouring object: its
//! outer contour is not a quadrilateral and the marker is lost before decoding. The ink of
//! the border is still the darkest thing in its neighbourhood, and the blurred margin is
//! still lighter than the ink by a good part of the local contrast. So the pixels of such a
//! component are cut again at a point a quarter of the way from the local minimum to the
//! local maximum (instead of half way), keeping only pixels dark at both cuts: the thin
//! bridges fall away, the ink of the border stays, and the components of the re-cut are
//! traced and fitted exactly like the first ones. The refined corners come from the grey
//! image, as always, so the darker cut costs no accuracy.
//!
//! Only components that are large enough to hold a marker and gave no quad are re-cut, and
//! only their own pixels (the labeller's runs of them), box by box (the union of the boxes
//! when their areas add up to more than the frame): a darker cut's components are parts of
//! the first cut's, so a marker already found or a speck inside the box could only give
//! parts of itself. Levels are computed only for the tiles those pixels cross (tile
//! statistics only for their 3 x 3 neighbourhoods), and only the pixels cut are labelled
//! (the labeller takes them piece by piece, not the whole box). A frame in
//! which every large component was a quad (the synthetic marker scenes) pays nothing; a
//! cluttered frame pays about one more quad-finding pass, plus the
//! refinement of the new quads the re-cut finds (on the clutter frames of the accuracy
//! scenes, quad finding took about twice as long with the re-cut, measured on a loaded
//! machine). Re-cut quads already found are dropped before the refinement, and so is a
//! re-cut component with no hole (counted by the labeller,
//! [`crate::contour::Component::holes`]) before its trace: a marker's light cells are holes
//! in its border's component, and on cluttered frames most of the re-cut's components are
//! solid pieces of texture (on ten 640x480 clutter frames the quads the decoder examined
//! fell from 261 to 70, with the same markers read).
//!
//! Known limit: a border whose far edge touches an object as dark as its ink (no margin left
//! after smoothing, not even a blurred one) stays merged; on the Duckietown frames five of
//! the 56 tags AprilTag 3 reads are so. The same boxes are then searched by boundary
//! clustering ([`crate::cluster`]), which reads them.

use crate::contour::{Labeller, trace_outer};
use crate::image::{Corners, GrayView};
use crate::quad::{QuadLimits, fit_quad};
use crate::threshold::DARK;

/// Tile side of the local minimum and maximum of the re-cut, in pixels (the neighbourhood is
/// 3 x 3 tiles, as in the first cut).
const TILE: usize = 8;

/// Where the re-cut lies between the local minimum (0) and maximum (1) grey level.
const CUT: f64 = 0.25;

/// Where the light cut of [`crate::Detector`]'s `split_retries` lies between the local
/// minimum (0) and maximum (1) grey level: at 0.7, a smeared border whose box blur covers
/// it for only half its length (a one-cell border next to a white cell under a motion of
/// two cells) still reads dark under blur sigma 1 and noise, while the white margin around
/// the marker stays light (at 9 px of motion blur, 0.6 read 2 markers more in 960 but once
/// gave a wrong code, 0.8 read 6 fewer).
pub(crate) const LIGHT_CUT: f64 = 0.7;

/// Least local contrast (max - min grey level over a 3 x 3 tile neighbourhood) in which
/// the light cut marks anything dark: a flat neighbourhood cut near its own maximum would
/// turn noise into dark blobs (the first cut's default `min_contrast` is the same).
pub(crate) const LIGHT_CUT_MIN_CONTRAST: u8 = 30;

/// A pixel rectangle, inclusive bounds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// Smallest x.
    pub x0: u32,
    /// Smallest y.
    pub y0: u32,
    /// Largest x.
    pub x1: u32,
    /// Largest y.
    pub y1: u32,
}

/// The parts of `runs` (`[y, x0, x1)` in raster order) inside the box `x0 ..= x1`, `y0 ..=
/// y1`, in order, as `(row, start, end)` in box coordinates (`end` exclusive, never empty).
fn runs_in(
    runs: &[[u32; 3]],
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
    let start = runs.partition_point(|q| (q[0] as usize) < y0);
    runs[start..]
        .iter()
        .take_while(move |q| q[0] as usize <= y1)
        .filter_map(move |q| {
            let (a, b) = ((q[1] as usize).max(x0), (q[2] as usize).min(x1 + 1));
            (a < b).then(|| (q[0] as usize - y0, a - x0, b - x0))
        })
}

/// The grey-level minimum and maximum of each square tile of a box of the image (the
/// re-cut's and boundary clustering's local thresholds), in scratch reused from box to box.
#[derive(Debug, Default, Clone)]
pub(crate) struct BoxTiles {
    /// Per tile, row-major.
    min: Vec<u8>,
    max: Vec<u8>,
    /// Tiles per row.
    tw: usize,
    /// Element-wise minimum and maximum of a tile row's pixel rows.
    row_min: Vec<u8>,
    row_max: Vec<u8>,
    /// Per tile, row-major: the minimum and maximum over the 3 x 3 tiles around it.
    lo: Vec<u8>,
    hi: Vec<u8>,
}

impl BoxTiles {
    /// The tiles (`tile` pixels square, the last of each row and column cut short) of the
    /// box at `(x0, y0)`, `cw x ch` pixels, of `img`; returns the tiles per row and column.
    pub(crate) fn compute(
        &mut self,
        img: &GrayView<'_>,
        x0: usize,
        y0: usize,
        cw: usize,
        ch: usize,
        tile: usize,
    ) -> (usize, usize) {
        self.compute_in(img, [x0, y0, cw, ch], tile, |_| (0, usize::MAX))
    }

    /// [`BoxTiles::compute`] where only the tiles `cols(ty)` (a range of tile columns,
    /// cut to the box; empty for none) of each tile row `ty` are needed: the others are
    /// left neutral (minimum 255, maximum 0), and [`BoxTiles::around`] is right for every
    /// tile whose 3 x 3 neighbourhood lies in the ranges.
    pub(crate) fn compute_in(
        &mut self,
        img: &GrayView<'_>,
        [x0, y0, cw, ch]: [usize; 4],
        tile: usize,
        cols: impl Fn(usize) -> (usize, usize),
    ) -> (usize, usize) {
        let (tw, th) = (cw.div_ceil(tile), ch.div_ceil(tile));
        self.tw = tw;
        self.min.clear();
        self.min.resize(tw * th, u8::MAX);
        self.max.clear();
        self.max.resize(tw * th, 0);
        self.row_min.resize(cw, 0);
        self.row_max.resize(cw, 0);
        // Element-wise over a tile row's pixel rows first (whole rows: this vectorises),
        // then each tile's columns.
        for ty in 0..th {
            let (c0, c1) = cols(ty);
            let c1 = c1.min(tw);
            if c0 >= c1 {
                continue;
            }
            let (p0, p1) = (c0 * tile, (c1 * tile).min(cw));
            let (row_min, row_max) = (&mut self.row_min[p0..p1], &mut self.row_max[p0..p1]);
            row_min.fill(u8::MAX);
            row_max.fill(0);
            for y in ty * tile..((ty + 1) * tile).min(ch) {
                let row = &img.row(y0 + y)[x0 + p0..x0 + p1];
                for ((lo, hi), &v) in row_min.iter_mut().zip(row_max.iter_mut()).zip(row) {
                    *lo = (*lo).min(v);
                    *hi = (*hi).max(v);
                }
            }
            let t = ty * tw;
            let (mins, maxs) = (&mut self.min[t + c0..t + c1], &mut self.max[t + c0..t + c1]);
            for (((a, b), lo), hi) in row_min
                .chunks(tile)
                .zip(row_max.chunks(tile))
                .zip(mins)
                .zip(maxs)
            {
                *lo = a.iter().copied().fold(u8::MAX, u8::min);
                *hi = b.iter().copied().fold(0, u8::max);
            }
        }
        // The 3 x 3 neighbourhoods, separably: over the tile rows above, at and below, then
        // over the tiles left, at and right (both cut to the box; a repeated tile changes
        // no extreme, so clamping the index does the cutting).
        self.lo.resize(tw * th, 0);
        self.hi.resize(tw * th, 0);
        let (vmin, vmax) = (&mut self.row_min[..tw], &mut self.row_max[..tw]);
        for ty in 0..th {
            let (u, d) = (ty.saturating_sub(1) * tw, (ty + 1).min(th - 1) * tw);
            let t = ty * tw;
            for tx in 0..tw {
                vmin[tx] = self.min[u + tx].min(self.min[t + tx]).min(self.min[d + tx]);
                vmax[tx] = self.max[u + tx].max(self.max[t + tx]).max(self.max[d + tx]);
            }
            for tx in 0..tw {
                let (l, r) = (tx.saturating_sub(1), (tx + 1).min(tw - 1));
                self.lo[t + tx] = vmin[l].min(vmin[tx]).min(vmin[r]);
                self.hi[t + tx] = vmax[l].max(vmax[tx]).max(vmax[r]);
            }
        }
        (tw, th)
    }

    /// The minimum and maximum over the 3 x 3 tiles around tile `(tx, ty)` (cut to the box).
    #[inline]
    pub(crate) fn around(&self, tx: usize, ty: usize) -> (u8, u8) {
        let i = ty * self.tw + tx;
        (self.lo[i], self.hi[i])
    }
}

/// Scratch buffers of the re-cut, reused from frame to frame.
#[derive(Debug, Default, Clone)]
pub struct Splitter {
    /// The re-cut binary image of one rectangle, with a light frame of one pixel; all
    /// light between calls (a call clears what it cut dark), so that a box needs no
    /// clearing of its own.
    bin: Vec<u8>,
    tiles: BoxTiles,
    /// Per tile: grey levels below this are cut dark.
    tile_cut: Vec<u8>,
    /// Per tile row: the tile columns whose statistics the cut needs, `[first, end)`.
    reach: Vec<(usize, usize)>,
    /// The levels of the current tile row, per pixel.
    row_cut: Vec<u8>,
    labeller: Labeller,
    contour: Vec<[i32; 2]>,
}

/// What the re-cut needs from the detector's settings.
#[derive(Debug, Clone, Copy)]
pub struct SplitParams<'a> {
    /// Quadrilateral acceptance limits.
    pub limits: &'a QuadLimits,
    /// Components closer than this to the frame border are rejected.
    pub border_margin: u32,
    /// Shortest side, pixels.
    pub min_side: u32,
}

impl Splitter {
    /// Re-cuts the pixels of `runs` (the dark runs, `[y, x0, x1)` in raster order, of the
    /// first cut's components that gave no quad) inside `rect` and calls `found` with the
    /// coarse corners (image pixel coordinates, clockwise in the image) of each
    /// quadrilateral traced there; the caller refines those it does not know yet.
    ///
    /// Only those components' pixels are cut again: the components of a darker cut are
    /// parts of the first cut's, so the other components in the box (markers already found,
    /// specks) could only give their own parts, which are no new markers.
    pub fn split(
        &mut self,
        img: &GrayView<'_>,
        runs: &[[u32; 3]],
        rect: Rect,
        params: &SplitParams<'_>,
        found: impl FnMut(Corners),
    ) {
        self.cut_at(img, Some(runs), rect, params, CUT, 0, found);
    }

    /// Cuts `img` inside `rect` at `cut` of the way from the local minimum to the local
    /// maximum (only pixels of `runs` too, when given: `[y, x0, x1)` in raster order;
    /// nothing where that neighbourhood's max - min is below `min_contrast`) and calls
    /// `found` with the coarse corners of each quadrilateral traced there.
    #[allow(clippy::too_many_arguments)]
    pub fn cut_at(
        &mut self,
        img: &GrayView<'_>,
        runs: Option<&[[u32; 3]]>,
        rect: Rect,
        params: &SplitParams<'_>,
        cut: f64,
        min_contrast: u8,
        mut found: impl FnMut(Corners),
    ) {
        let (w, h) = (img.width(), img.height());
        let (x0, y0) = (rect.x0 as usize, rect.y0 as usize);
        let (x1, y1) = ((rect.x1 as usize).min(w - 1), (rect.y1 as usize).min(h - 1));
        if x1 < x0 || y1 < y0 {
            return;
        }
        let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
        let (tw, th) = (cw.div_ceil(TILE), ch.div_ceil(TILE));
        // Each tile's cut as an integer: a grey level `v` is below `lo + cut (hi - lo)`
        // exactly when it is below that value rounded up (0 where nothing is cut).
        self.tile_cut.clear();
        self.tile_cut.resize(tw * th, 0);
        // With runs, only the tiles they cross need a level (elsewhere nothing is cut):
        // `tile_cut` first marks them (1), then holds their levels. Their neighbourhoods
        // need tile statistics: per tile row, the columns of the tiles marked in it and the
        // rows next to it, one more either side (`reach`, first and past-the-last column).
        self.reach.clear();
        if let Some(runs) = runs {
            self.reach.resize(th, (usize::MAX, 0));
            for (y, a, b) in runs_in(runs, x0, y0, x1, y1) {
                let ty = y / TILE;
                let t = ty * tw;
                let (ca, cb) = (a / TILE, (b - 1) / TILE);
                self.tile_cut[t + ca..=t + cb].fill(1);
                for r in ty.saturating_sub(1)..(ty + 2).min(th) {
                    let span = &mut self.reach[r];
                    *span = (span.0.min(ca.saturating_sub(1)), span.1.max(cb + 2));
                }
            }
        } else {
            self.reach.resize(th, (0, tw));
        }
        // Tile statistics over those tiles of the rectangle.
        let reach = &self.reach;
        self.tiles
            .compute_in(img, [x0, y0, cw, ch], TILE, |ty| reach[ty]);
        for ty in 0..th {
            for tx in 0..tw {
                if runs.is_some() && self.tile_cut[ty * tw + tx] == 0 {
                    continue;
                }
                self.tile_cut[ty * tw + tx] = 0;
                let (lo, hi) = self.tiles.around(tx, ty);
                if hi - lo < min_contrast {
                    continue;
                }
                // In [lo, hi]: the rounding up stays a grey level. Rounded up by a cast
                // (exact for a non-negative level; `ceil` is a software call without
                // SSE4.1).
                let level = (f64::from(lo) + cut * f64::from(hi - lo)).clamp(0.0, 255.0);
                let whole = level as u8;
                self.tile_cut[ty * tw + tx] = whole + u8::from(f64::from(whole) < level);
            }
        }
        // The re-cut, with a light frame of one pixel so that no component touches it. The
        // buffer is all light between calls (what a call cuts dark it clears again), so
        // only the pixels cut need writing and clearing.
        let (bw, bh) = (cw + 2, ch + 2);
        if self.bin.len() < bw * bh {
            self.bin.resize(bw * bh, 0);
        }
        self.cut_rows(img, runs, [x0, y0, x1, y1], tw);
        let m = params.border_margin.max(1) as usize;
        let min_side = params.min_side;
        let Self {
            bin: sbin,
            labeller,
            contour,
            ..
        } = self;
        for &c in labeller.finish() {
            let cbw = c.x_max - c.x_min + 1;
            let cbh = c.y_max - c.y_min + 1;
            // Image coordinates of the component's box (the frame adds one pixel).
            let (ix0, iy0) = (x0 + c.x_min as usize - 1, y0 + c.y_min as usize - 1);
            let (ix1, iy1) = (x0 + c.x_max as usize - 1, y0 + c.y_max as usize - 1);
            // A component without holes is no marker's border (its light cells would be
            // holes in it): on cluttered frames most of the re-cut's components are such
            // solid pieces of dark texture, and they cost the trace and the fit.
            if cbw.max(cbh) < min_side
                || cbw.min(cbh) < min_side / 2
                || c.holes == 0
                || c.pixels < cbw.max(cbh) + cbw.min(cbh)
                || ix0 < m
                || iy0 < m
                || ix1 + m >= w
                || iy1 + m >= h
            {
                continue;
            }
            let max_len = 2 * (cbw + cbh) as usize + 16;
            if !trace_outer(sbin, bw, c.start_x, c.y_min, max_len, contour) {
                continue;
            }
            let Some(coarse) = fit_quad(contour, params.limits) else {
                continue;
            };
            let (ox, oy) = (x0 as f64 - 1.0, y0 as f64 - 1.0);
            found(coarse.map(|p| nalgebra::Point2::new(p.x + ox, p.y + oy)));
        }
        // Light again: every dark pixel is in a run of the labelling. The runs come in
        // raster order; each row is cleared once, from its first run's start to its last
        // run's end (what lies between is light already).
        let mut clear = |(y, a, b): (u32, u32, u32)| {
            let row = y as usize * bw;
            sbin[row + a as usize..row + b as usize].fill(0);
        };
        let mut span: Option<(u32, u32, u32)> = None;
        for (_, y, a, b) in labeller.runs() {
            match span {
                Some((sy, sa, _)) if sy == y => span = Some((sy, sa, b)),
                _ => {
                    if let Some(s) = span {
                        clear(s);
                    }
                    span = Some((y, a, b));
                }
            }
        }
        if let Some(s) = span {
            clear(s);
        }
    }

    /// The cut of the re-cut's box `[x0, y0, x1, y1]` (inclusive; `tw` tiles across, levels in
    /// `tile_cut`): every pixel of `runs` there (every pixel of the box without runs) below its
    /// tile's level is dark in `bin` (framed, `x1 - x0 + 3` wide), and the labeller is given
    /// the cut pixels (a labelling begun, not finished).
    fn cut_rows(
        &mut self,
        img: &GrayView<'_>,
        runs: Option<&[[u32; 3]]>,
        [x0, y0, x1, y1]: [usize; 4],
        tw: usize,
    ) {
        let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
        let bw = cw + 2;
        self.row_cut.clear();
        self.row_cut.resize(cw, 0);
        // With runs: those in the box, in order.
        let mut runs = runs.map(|r| runs_in(r, x0, y0, x1, y1).peekable());
        self.labeller.begin();
        for y in 0..ch {
            if y % TILE == 0 {
                // Each tile's level spread over its pixels, so that the cut is one pass over
                // whole rows (which vectorises).
                let cuts = &self.tile_cut[(y / TILE) * tw..(y / TILE + 1) * tw];
                for (chunk, &t) in self.row_cut.chunks_mut(TILE).zip(cuts) {
                    chunk.fill(t);
                }
            }
            let row = &img.row(y0 + y)[x0..=x1];
            let out = &mut self.bin[(y + 1) * bw + 1..(y + 1) * bw + 1 + cw];
            let cut_piece = |out: &mut [u8], a: usize, b: usize| {
                for ((o, &v), &t) in out[a..b]
                    .iter_mut()
                    .zip(&row[a..b])
                    .zip(&self.row_cut[a..b])
                {
                    *o = u8::from(v < t) * DARK;
                }
            };
            // The pixels of the row cut, then handed to the labeller in one piece from the
            // first cut pixel to the last: the pixels between the runs are light (the
            // buffer is light between calls), and no run spans two runs of the first cut,
            // which light pixels separate, so the runs are those of each piece, in order.
            let (mut first, mut end) = (usize::MAX, 0);
            match runs.as_mut() {
                Some(runs) => {
                    while let Some((_, a, b)) = runs.next_if(|r| r.0 == y) {
                        cut_piece(out, a, b);
                        first = first.min(a);
                        end = b;
                    }
                }
                None => {
                    cut_piece(out, 0, cw);
                    (first, end) = (0, cw);
                }
            }
            if first < end {
                self.labeller
                    .add_row((y + 1) as u32, (first + 1) as u32, &out[first..end]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The cut written out pixel by pixel: the rectangle's 8-px tiles, each pixel against
    /// `lo + cut (hi - lo)` over its tile's 3 x 3 tile neighbourhood (nothing where `hi -
    /// lo` is below `min_contrast`), and dark in `first` too when given.
    fn reference(
        px: &[u8],
        w: usize,
        first: Option<&[u8]>,
        rect: Rect,
        cut: f64,
        min_contrast: u8,
    ) -> Vec<u8> {
        let (x0, y0, x1, y1) = (
            rect.x0 as usize,
            rect.y0 as usize,
            rect.x1 as usize,
            rect.y1 as usize,
        );
        let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
        let (tw, th) = (cw.div_ceil(TILE), ch.div_ceil(TILE));
        let mut out = vec![0u8; (cw + 2) * (ch + 2)];
        for y in 0..ch {
            for x in 0..cw {
                let (tx, ty) = (x / TILE, y / TILE);
                let (mut lo, mut hi) = (u8::MAX, 0u8);
                for yy in 0..ch {
                    for xx in 0..cw {
                        if (xx / TILE).abs_diff(tx) <= 1 && (yy / TILE).abs_diff(ty) <= 1 {
                            let v = px[(y0 + yy) * w + x0 + xx];
                            lo = lo.min(v);
                            hi = hi.max(v);
                        }
                    }
                }
                let _ = (tw, th);
                if hi - lo < min_contrast {
                    continue;
                }
                let v = px[(y0 + y) * w + x0 + x];
                let dark_first = first.is_none_or(|b| b[(y0 + y) * w + x0 + x] == DARK);
                if dark_first && f64::from(v) < f64::from(lo) + cut * f64::from(hi - lo) {
                    out[(y + 1) * (cw + 2) + x + 1] = DARK;
                }
            }
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The tiled, integer cut of `cut_at` is the pixel-by-pixel rule, with and without
        /// the runs of a first binary image, at the re-cut's and the light cut's levels.
        #[test]
        fn cut_matches_the_pixel_rule(
            w in 1usize..40,
            h in 1usize..40,
            seed in any::<u64>(),
            light in any::<bool>(),
            corner in (0usize..40, 0usize..40, 0usize..40, 0usize..40),
        ) {
            let mut state = seed | 1;
            let mut next = || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state
            };
            let px: Vec<u8> = (0..w * h).map(|_| (next() % 256) as u8).collect();
            let first: Vec<u8> = (0..w * h).map(|_| u8::from(next() % 3 != 0)).collect();
            let (a, b) = (corner.0 % w, corner.1 % w);
            let (c, d) = (corner.2 % h, corner.3 % h);
            let rect = Rect { x0: a.min(b) as u32, x1: a.max(b) as u32, y0: c.min(d) as u32, y1: c.max(d) as u32 };
            let img = GrayView::new(&px, w, h).unwrap();
            let limits = QuadLimits { min_side: 4.0, min_angle_deg: 20.0, line_tolerance: 1.0, line_tolerance_rel: 0.05 };
            let params = SplitParams { limits: &limits, border_margin: 1, min_side: 4 };
            // The dark runs of `first`, as the labeller gives them.
            let mut runs = Vec::new();
            for y in 0..h {
                let mut x = 0;
                while x < w {
                    if first[y * w + x] != DARK {
                        x += 1;
                        continue;
                    }
                    let x0 = x;
                    while x < w && first[y * w + x] == DARK {
                        x += 1;
                    }
                    runs.push([y as u32, x0 as u32, x as u32]);
                }
            }
            let mut s = Splitter::default();
            let (given, runs, cut, min_contrast) = if light {
                (None, None, LIGHT_CUT, LIGHT_CUT_MIN_CONTRAST)
            } else {
                (Some(first.as_slice()), Some(runs.as_slice()), CUT, 0)
            };
            // Twice on one splitter, so that what a call leaves behind would show.
            for _ in 0..2 {
                s.cut_at(&img, runs, rect, &params, cut, min_contrast, |_| {});
                // The cut, from the runs the labeller was given (framed box coordinates).
                let bw = (rect.x1 - rect.x0 + 3) as usize;
                let mut cut_image = vec![0u8; bw * (rect.y1 - rect.y0 + 3) as usize];
                for (_, y, a, b) in s.labeller.runs() {
                    cut_image[y as usize * bw + a as usize..y as usize * bw + b as usize].fill(DARK);
                }
                prop_assert_eq!(cut_image, reference(&px, w, given, rect, cut, min_contrast));
                // The cut's buffer is light again for the next box.
                prop_assert!(s.bin.iter().all(|&v| v == 0));
            }
        }
    }
}
