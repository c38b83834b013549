//! Corner refinement with the decoded cell pattern (issue #13).
//!
//! [`crate::refine`] locates each edge against dark and light levels taken from the edge
//! profiles themselves (low percentiles of their minima and maxima). On a small marker those
//! profiles never reach the levels: the one-cell border is only a few pixels wide, so blur
//! lifts its darkest point, by more where the data cell inside it is white. These level
//! errors move each side by a few hundredths of a pixel, differently on each side, and they
//! are the larger part of the corner error of small markers: with the scene's exact levels
//! substituted, the corner RMS of 20-40 px markers (blur 1, noise 3) falls from 0.055 to
//! 0.033 px.
//!
//! Once a marker is decoded its whole cell pattern is known, so the levels and the blur can
//! be fitted to it, and the edge rule's remaining bias modelled:
//! - **Levels and blur.** The grey level is sampled at 3 x 3 points of every cell (border
//!   included) and fitted by `v = lo + contrast W_s`, where `W_s` is the whiteness of the
//!   known pattern (inside a white surround) under a Gaussian blur of `s` pixels, separable
//!   over the cell grid. For each `s` the fit is linear least squares; `s` walks a grid
//!   downhill in misfit and is then interpolated by a parabola.
//! - **Light across the marker.** Uniform levels are wrong under a light gradient. The
//!   gradient is read from the quiet zone's level on opposite sides (the median of each
//!   side's profile maxima), but only where the profiles' outer halves fit in a one-cell
//!   quiet zone with three blur sigmas to spare: beyond it lies whatever the marker is on,
//!   whose blur reads as a gradient of up to about 2 %. Where the profiles reach further,
//!   readings up to 2 % are taken as none, and larger ones are used only when the quiet
//!   zone's level along the sides between slopes the same way by about as much (light that
//!   differs between opposite sides changes along the sides between them; a different
//!   surround does not); a marker whose reading is not confirmed keeps its plain corners.
//! - **Edges.** Each side's edge profiles are sampled as in the plain refinement's second
//!   pass, and the edge is located by the same midpoint-and-area rule against the fitted
//!   levels. Two blurs the rule does not expect are modelled: the white of a white inner
//!   neighbour reaching the border (a bias computed by running the rule on the modelled
//!   profile, for the border's local width, which perspective changes along the side), and
//!   near a corner the white beyond the adjacent side (which scales the dark part of the
//!   profile by the share of the blur that falls on the side).
//!
//! Accuracy scenes (8 markers of 20-120 px, perspective 0.12, blur 1, noise 3, seeds 50,000
//! on), corner RMS with and without this step:
//!
//! | side | own family | tag36h11 |
//! |---|---|---|
//! | 20-40 px | 0.055 -> 0.027 | 0.063 -> 0.026 |
//! | 40-60 px | 0.030 -> 0.020 | 0.033 -> 0.017 |
//!
//! Only markers whose cells are under [`MAX_CELL_PX`] are refined this way (larger markers
//! gain little), and the plain corners are kept whenever the model cannot be fitted or moves
//! a corner further than a plain refinement error could be. Markers read as motion-blurred
//! are refined too: their edges are not Gaussian, but the fitted blur absorbs a short motion
//! (`cargo xtask detector-accuracy --motion-blur`: corner RMS at 3 and 5 px of motion 0.046
//! -> 0.042 and 0.119 -> 0.116 px, at 9 and 13 px within 2 %), and in still scenes the few
//! small markers that the plain reading misses and the motion-blurred one reads would
//! otherwise keep the plain refinement's 0.14 px. It costs about as much as the plain
//! refinement per marker; [`crate::refine::RefineConfig::with_pattern`] turns it off.

use crate::cross_ratio::CrossRatioFrame;
use crate::family::MarkerFamily;
use crate::image::{Corners, GrayView};
use crate::refine::{
    Line, PROFILE, RefineConfig, STEP, SideFrame, edge_in_profile, fit_line_trimmed, intersect,
    sample_profile,
};
use crate::sides::normal_cdf;
use nalgebra::Point2;

/// Largest marker, border included, in cells (8 x 8 data cells).
pub(crate) const MAX_CELLS: usize = 10;

/// Sub-positions (cells, from the cell centre) at which every cell is sampled for the levels.
const SUB: [f64; 3] = [-0.25, 0.0, 0.25];

/// Blur widths (pixels) tried for the level fit.
const SIGMAS: [f64; 9] = [0.4, 0.55, 0.75, 1.0, 1.3, 1.7, 2.2, 3.0, 4.0];

/// Where the search over [`SIGMAS`] starts (1 px).
const START_SIGMA: usize = 3;

/// Most points sampled for the levels.
const MAX_POINTS: usize = MAX_CELLS * MAX_CELLS * SUB.len() * SUB.len();

/// Relative light gradients (per half marker) up to this are taken as none: noise and the
/// sides' different profile lengths read uniform light as gradients of 0.2 % on average.
const MIN_GRADIENT: f64 = 0.006;

/// The quiet zone's level is read from the profiles only when their outer half plus this
/// many blur sigmas fits in one cell (the quiet zone of a printed tag): otherwise what lies
/// beyond it, which differs from side to side, would read as a light gradient.
const QUIET_BLUR_MARGIN: f64 = 3.0;

/// Where the profiles reach beyond a one-cell quiet zone, what lies there blurs into the
/// quiet zone's level and reads as a light gradient of up to about this much (relative, per
/// half marker): flat levels are used up to it, and a larger reading only where the levels
/// along the sides between confirm it ([`SLOPE_AGREEMENT`]); otherwise the plain corners are
/// kept. Before, every such marker kept its plain corners: under a 3:1 light ratio across
/// the frame that left 40-60 px markers at 0.080 px corner RMS (now 0.049; 20-40 px 0.087 ->
/// 0.070; `cargo xtask detector-accuracy --sizes 300000`, seeds never tuned on).
const MIN_UNSEEN_GRADIENT: f64 = 0.02;

/// How the quiet zone's relative slope along the sides between must compare with a gradient
/// read across the marker beyond the quiet zone (same sign, this share of it), on both axes,
/// for the reading to be used. Under a 3:1 light ratio they mostly show 0.45-1.0 of it. Where a
/// different surround beyond a side makes the reading, the slope is nil, opposite or out of
/// proportion, as for the reading that, used, put the tag36h11 rig's Fig. 11 robot 2 heading
/// 18 deg off. Taking readings confirmed by a quarter of their size moved 19 of the 56
/// Duckietown tags by up to 0.46 px, away from AprilTag 3's corners on average (RMS distance
/// on those 0.154 -> 0.168 px); with this range 4 move, by 0.06-0.11 px (over all 56 tags
/// the distance is 0.2067 px before, 0.2066 after).
const SLOPE_AGREEMENT: [f64; 2] = [0.4, 1.6];

/// Most stations per side (the plain refinement's 64 add nothing measurable on markers
/// small enough to be refined here, and cost time).
const MAX_STATIONS: usize = 32;

/// Only markers whose cells are smaller than this (pixels, the smaller of the two
/// dimensions) are refined: on larger ones the plain refinement's profiles reach the levels
/// and the corner RMS gain is under a tenth (0.0170 -> 0.0151 px at 60-130 px), for about
/// as much time again as the plain refinement.
const MAX_CELL_PX: f64 = 8.0;

/// Range and resolution of [`phi`]'s table.
const PHI_RANGE: f64 = 8.0;
const PHI_STEPS: usize = 4096;

/// `f` at `N` points evenly spread over `[-range, range]`, ends included.
pub(crate) fn tabulate<const N: usize>(range: f64, f: impl Fn(f64) -> f64) -> [f64; N] {
    let mut t = [0.0; N];
    for (k, v) in t.iter_mut().enumerate() {
        *v = f(-range + 2.0 * range * k as f64 / (N - 1) as f64);
    }
    t
}

/// A table of [`tabulate`] over `[-range, range]` interpolated linearly at `x`; `None`
/// outside the range (NaN included).
#[inline]
pub(crate) fn interpolate<const N: usize>(table: &[f64; N], range: f64, x: f64) -> Option<f64> {
    let steps = (N - 1) as f64;
    let pos = (x + range) * (steps / (2.0 * range));
    if pos.is_nan() || pos <= 0.0 || pos >= steps {
        return None;
    }
    // Positive here, so truncation is floor.
    let k = pos as usize;
    Some(table[k] + (table[k + 1] - table[k]) * (pos - k as f64))
}

/// The standard normal distribution function, interpolated in a table (error under 1e-6;
/// the level fit evaluates it a few thousand times per marker). NaN reads as 0.
#[inline]
pub(crate) fn phi(x: f64) -> f64 {
    static TABLE: std::sync::OnceLock<[f64; PHI_STEPS + 1]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| tabulate(PHI_RANGE, normal_cdf));
    interpolate(table, PHI_RANGE, x).unwrap_or(if x > 0.0 { 1.0 } else { 0.0 })
}

/// The marker's cells, border included: `black[row][col]`.
pub(crate) struct Cells {
    pub(crate) rows: usize,
    pub(crate) cols: usize,
    pub(crate) black: [[bool; MAX_CELLS]; MAX_CELLS],
}

impl Cells {
    pub(crate) fn new(family: MarkerFamily, code: u64) -> Option<Self> {
        let (rows, cols) = (family.rows() as usize + 2, family.cols() as usize + 2);
        if rows > MAX_CELLS || cols > MAX_CELLS {
            return None;
        }
        let mut black = [[false; MAX_CELLS]; MAX_CELLS];
        for (r, row) in black.iter_mut().enumerate().take(rows) {
            for (c, b) in row.iter_mut().enumerate().take(cols) {
                *b = r == 0
                    || c == 0
                    || r == rows - 1
                    || c == cols - 1
                    || family.bit(code, (r - 1) as u32, (c - 1) as u32);
            }
        }
        Some(Self { rows, cols, black })
    }

    /// The mean cell width and height in pixels of a marker with these cells and `corners`
    /// (the border's outer corners): the mean length of the top and bottom sides over the
    /// columns, of the left and right sides over the rows.
    pub(crate) fn cell_px(&self, corners: &Corners) -> (f64, f64) {
        (
            mean_length(corners, 0) / self.cols as f64,
            mean_length(corners, 1) / self.rows as f64,
        )
    }

    /// Cells along side `side` (0 top, 1 right, 2 bottom, 3 left, clockwise from the NW
    /// corner).
    fn along(&self, side: usize) -> usize {
        if side.is_multiple_of(2) {
            self.cols
        } else {
            self.rows
        }
    }

    /// Cells across side `side`.
    fn across(&self, side: usize) -> usize {
        if side.is_multiple_of(2) {
            self.rows
        } else {
            self.cols
        }
    }

    /// Whether the cell `depth` cells in from side `side`, `j` cells along it (counted in the
    /// side's clockwise direction) is black.
    fn black_from_side(&self, side: usize, depth: usize, j: usize) -> bool {
        let (r, c) = match side {
            0 => (depth, j),
            1 => (j, self.cols - 1 - depth),
            2 => (self.rows - 1 - depth, self.cols - 1 - j),
            _ => (self.rows - 1 - j, depth),
        };
        self.black[r][c]
    }
}

/// The marker's fitted levels and blur.
#[derive(Debug, Clone, Copy)]
struct LevelModel {
    /// Dark (ink) level and white minus dark, grey levels.
    lo: f64,
    contrast: f64,
    /// Blur sigma, pixels.
    sigma: f64,
}

/// Scratch of the pattern refinement (fixed-size, owned by the detector).
#[derive(Debug, Clone)]
pub(crate) struct PatternRefiner {
    /// Grey level and sample-grid indices (column, row) of each level sample.
    values: Vec<f64>,
    index: Vec<[u16; 2]>,
    pts: Vec<[f64; 3]>,
    profiles: Vec<[f64; PROFILE]>,
}

impl Default for PatternRefiner {
    fn default() -> Self {
        Self {
            values: Vec::with_capacity(MAX_POINTS),
            index: Vec::with_capacity(MAX_POINTS),
            pts: Vec::with_capacity(MAX_STATIONS),
            profiles: Vec::with_capacity(4 * MAX_STATIONS),
        }
    }
}

/// Mean length of two opposite sides of `c`: `0` for top/bottom, `1` for left/right.
fn mean_length(c: &Corners, pair: usize) -> f64 {
    let len = |i: usize| {
        let (p, q) = (c[i], c[(i + 1) % 4]);
        (q[0] - p[0]).hypot(q[1] - p[1])
    };
    if pair == 0 {
        0.5 * (len(0) + len(2))
    } else {
        0.5 * (len(1) + len(3))
    }
}

impl PatternRefiner {
    /// Refines the corners (the marker's own NW, NE, SE, SW, clockwise in the image) of a
    /// decoded marker with `cells`. `None` when the pattern model does not fit (the caller
    /// keeps its corners).
    pub(crate) fn refine(
        &mut self,
        img: &GrayView<'_>,
        corners: &Corners,
        cells: &Cells,
        cfg: &RefineConfig,
    ) -> Option<Corners> {
        let plain = *corners;
        let (cw, ch) = cells.cell_px(&plain);
        if !(cw >= 1.0 && ch >= 1.0) || cw.min(ch) >= MAX_CELL_PX {
            return None;
        }
        let frame = CrossRatioFrame::new(corners).ok()?;
        let model = self.fit_levels(img, &frame, cells, cw, ch)?;
        let mut lines = [Line {
            n: [0.0, 0.0],
            c: 0.0,
        }; 4];
        let mut geoms = [None; 4];
        for (side, g) in geoms.iter_mut().enumerate() {
            *g = Self::geometry(&plain, &frame, cells, side, cw, ch, cfg);
        }
        let [Some(g0), Some(g1), Some(g2), Some(g3)] = geoms else {
            return None;
        };
        let geoms = [g0, g1, g2, g3];
        self.profiles.clear();
        let mut quiet = [0.0; 4];
        let mut slope = [0.0; 4];
        for ((g, q), t) in geoms.iter().zip(quiet.iter_mut()).zip(slope.iter_mut()) {
            (*q, *t) = self.sample(img, g);
        }
        // Light across the marker, from the quiet zone's level on opposite sides (the same
        // blur and pattern on each, so only the light differs): 1 + ga a + gb b.
        let ratio = |hi: f64, lo: f64| {
            let r = (hi - lo) / (hi + lo);
            if r.is_finite() && r.abs() > MIN_GRADIENT {
                r
            } else {
                0.0
            }
        };
        // Only where the profiles' outer halves stay inside a one-cell quiet zone, blur
        // included: beyond it lies whatever the marker is on, which differs from side to side.
        let inside = geoms.iter().all(|g| {
            g.half + QUIET_BLUR_MARGIN * model.sigma <= g.across_ends[0].min(g.across_ends[1])
        });
        let (ga, gb) = (ratio(quiet[1], quiet[3]), ratio(quiet[2], quiet[0]));
        // Where the profiles reach beyond the quiet zone, a reading over 2 % is used only if
        // the quiet zone's level along the sides between slopes the same way by about as
        // much, on both axes: light that differs between opposite sides also changes along
        // the sides between them, a different surround beyond one side does not. A reading
        // they do not confirm keeps the plain corners.
        let (ga, gb) = if inside {
            (ga, gb)
        } else if ga.abs().max(gb.abs()) <= MIN_UNSEEN_GRADIENT {
            (0.0, 0.0)
        } else {
            let agrees = |across: f64, along: f64| {
                (across.abs() <= MIN_UNSEEN_GRADIENT && along.abs() <= MIN_UNSEEN_GRADIENT)
                    || (across * along > 0.0
                        && (SLOPE_AGREEMENT[0] * across.abs()..=SLOPE_AGREEMENT[1] * across.abs())
                            .contains(&along.abs()))
            };
            if !(agrees(ga, 0.5 * (slope[0] - slope[2])) && agrees(gb, 0.5 * (slope[1] - slope[3])))
            {
                return None;
            }
            let over = |g: f64| {
                if g.abs() > MIN_UNSEEN_GRADIENT {
                    g
                } else {
                    0.0
                }
            };
            (over(ga), over(gb))
        };
        let light = move |a: f64, b: f64| 1.0 + ga * a + gb * b;
        let mut first = 0;
        for (g, line) in geoms.iter().zip(lines.iter_mut()) {
            *line = self.side(g, first, cells, &model, light, cfg)?;
            first += g.count;
        }
        let mut out = [Point2::origin(); 4];
        for (i, corner) in out.iter_mut().enumerate() {
            *corner = intersect(&lines[(i + 3) % 4], &lines[i])?.into();
        }
        // The plain refinement is within a fraction of a pixel; anything further is a failed
        // model, not a correction.
        let limit = 0.5f64.max(0.05 * cw.min(ch));
        for (c, k) in out.iter().zip(&plain) {
            let moved = (k[0] - c[0]).hypot(k[1] - c[1]);
            if moved.is_nan() || moved > limit {
                return None;
            }
        }
        Some(out)
    }

    /// Samples every cell and fits the levels and the blur.
    fn fit_levels(
        &mut self,
        img: &GrayView<'_>,
        frame: &CrossRatioFrame,
        cells: &Cells,
        cw: f64,
        ch: f64,
    ) -> Option<LevelModel> {
        self.values.clear();
        self.index.clear();
        let (rows, cols) = (cells.rows, cells.cols);
        for r in 0..rows {
            for (si, sy) in SUB.iter().enumerate() {
                let v = r as f64 + 0.5 + sy;
                let b = -1.0 + 2.0 * v / rows as f64;
                for c in 0..cols {
                    for (sj, sx) in SUB.iter().enumerate() {
                        let u = c as f64 + 0.5 + sx;
                        let a = -1.0 + 2.0 * u / cols as f64;
                        let p = frame.map(a, b)?;
                        let g = crate::refine::bilinear(img, p.x, p.y);
                        self.values.push(g);
                        self.index
                            .push([(c * SUB.len() + sj) as u16, (r * SUB.len() + si) as u16]);
                    }
                }
            }
        }
        // Walk the grid downhill from sigma 1 px until a grid point is lower than both its
        // neighbours (the misfit has one minimum in practice): three to five fits.
        let mut fits = [f64::NAN; SIGMAS.len()];
        let eval = |k: usize, fits: &mut [f64; SIGMAS.len()]| -> f64 {
            if fits[k].is_nan() {
                fits[k] = self
                    .fit_at(cells, SIGMAS[k], cw, ch, true)
                    .map_or(f64::INFINITY, |(sse, _)| sse);
            }
            fits[k]
        };
        let mut k = START_SIGMA;
        loop {
            let here = eval(k, &mut fits);
            let down = if k > 0 {
                eval(k - 1, &mut fits)
            } else {
                f64::INFINITY
            };
            let up = if k + 1 < SIGMAS.len() {
                eval(k + 1, &mut fits)
            } else {
                f64::INFINITY
            };
            if down < here && down <= up {
                k -= 1;
            } else if up < here {
                k += 1;
            } else {
                break;
            }
        }
        if !fits[k].is_finite() {
            return None;
        }
        let best = self.fit_at(cells, SIGMAS[k], cw, ch, true);
        let (_, mut model) = best?;
        // Parabola through the best grid point and its neighbours (in log sigma), then the
        // levels from every sample at that blur.
        let mut sigma = model.sigma;
        if let Some(k) = SIGMAS.iter().position(|&s| s == model.sigma)
            && k > 0
            && k + 1 < SIGMAS.len()
            && fits[k - 1].is_finite()
            && fits[k + 1].is_finite()
        {
            let (l0, l1, l2) = (SIGMAS[k - 1].ln(), SIGMAS[k].ln(), SIGMAS[k + 1].ln());
            let (f0, f1, f2) = (fits[k - 1], fits[k], fits[k + 1]);
            let den = (l1 - l0) * (f1 - f2) - (l1 - l2) * (f1 - f0);
            let num = (l1 - l0).powi(2) * (f1 - f2) - (l1 - l2).powi(2) * (f1 - f0);
            if den.abs() > 0.0 {
                let l = l1 - 0.5 * num / den;
                if l.is_finite() && l > l0 && l < l2 {
                    sigma = l.exp();
                }
            }
        }
        if let Some((_, m)) = self.fit_at(cells, sigma, cw, ch, false) {
            model = m;
        }
        (model.contrast > 0.0 && model.lo.is_finite()).then_some(model)
    }

    /// Least-squares levels for blur `sigma` (pixels): the misfit and the model.
    fn fit_at(
        &self,
        cells: &Cells,
        sigma: f64,
        cw: f64,
        ch: f64,
        centres_only: bool,
    ) -> Option<(f64, LevelModel)> {
        let (rows, cols) = (cells.rows, cells.cols);
        let n = SUB.len();
        let wanted = |i: usize| !centres_only || i % n != 1;
        // bx[ui][c]: share of cell column c in the blur around sample column ui.
        let mut bx = [[0.0f64; MAX_CELLS]; MAX_CELLS * SUB.len()];
        let mut by = [[0.0f64; MAX_CELLS]; MAX_CELLS * SUB.len()];
        let shares =
            |count: usize, cell: f64, out: &mut [[f64; MAX_CELLS]; MAX_CELLS * SUB.len()]| {
                let s = sigma / cell;
                for (ui, row) in out.iter_mut().enumerate().take(count * n) {
                    if !wanted(ui) {
                        continue;
                    }
                    let u = (ui / n) as f64 + 0.5 + SUB[ui % n];
                    let mut prev = phi(-u / s);
                    for (c, share) in row.iter_mut().enumerate().take(count) {
                        let next = phi((c as f64 + 1.0 - u) / s);
                        *share = next - prev;
                        prev = next;
                    }
                }
            };
        shares(cols, cw, &mut bx);
        shares(rows, ch, &mut by);
        // rowsum[ui][r]: black share of cell row r around sample column ui.
        let mut rowsum = [[0.0f64; MAX_CELLS]; MAX_CELLS * SUB.len()];
        for (ui, rs) in rowsum.iter_mut().enumerate().take(cols * n) {
            if !wanted(ui) {
                continue;
            }
            for (r, v) in rs.iter_mut().enumerate().take(rows) {
                *v = (0..cols)
                    .filter(|&c| cells.black[r][c])
                    .map(|c| bx[ui][c])
                    .sum();
            }
        }
        // Flat levels first: v = lo + contrast w.
        let (mut s1, mut sw, mut sww, mut sv, mut swv, mut vv) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        // Rows further than 4 sigma from a sample row add nothing: the window of rows each
        // sample row sees.
        let reach = 4.0 * sigma / ch + 0.5;
        let mut window = [(0usize, 0usize); MAX_CELLS * SUB.len()];
        for (vi, w) in window.iter_mut().enumerate().take(rows * n) {
            let v = (vi / n) as f64 + 0.5 + SUB[vi % n];
            *w = (
                (v - reach).max(0.0) as usize,
                ((v + reach).ceil() as usize).min(rows),
            );
        }
        let w_of = |ui: usize, vi: usize| -> f64 {
            let (r0, r1) = window[vi];
            1.0 - (r0..r1).map(|r| by[vi][r] * rowsum[ui][r]).sum::<f64>()
        };
        for (&g, &[ui, vi]) in self.values.iter().zip(&self.index) {
            let (ui, vi) = (ui as usize, vi as usize);
            if !(wanted(ui) && wanted(vi)) {
                continue;
            }
            let w = w_of(ui, vi);
            s1 += 1.0;
            sw += w;
            sww += w * w;
            sv += g;
            swv += w * g;
            vv += g * g;
        }
        let det = s1 * sww - sw * sw;
        if det.is_nan() || det.abs() <= 1e-9 * s1 * sww {
            return None;
        }
        let lo = (sww * sv - sw * swv) / det;
        let contrast = (s1 * swv - sw * sv) / det;
        let sse = vv - lo * sv - contrast * swv;
        let model = LevelModel {
            lo,
            contrast,
            sigma,
        };
        (sse.is_finite() && lo.is_finite() && contrast.is_finite()).then_some((sse, model))
    }

    /// Where the edge profiles of side `side` (clockwise from the NW corner) are taken.
    fn geometry(
        corners: &Corners,
        frame: &CrossRatioFrame,
        cells: &Cells,
        side: usize,
        cw: f64,
        ch: f64,
        cfg: &RefineConfig,
    ) -> Option<SideGeom> {
        let a: [f64; 2] = corners[side].into();
        let frame_of_side = SideFrame::new(a, corners[(side + 1) % 4].into(), cfg)?;
        let SideFrame {
            len,
            t,
            n,
            margin,
            usable,
        } = frame_of_side;
        let count = ((usable / cfg.station_spacing.max(0.5)) as usize + 1)
            .clamp(2, cfg.max_stations.clamp(2, MAX_STATIONS));

        let spacing = usable / (count - 1) as f64;
        // Border width across this side and cell length along it, pixels.
        let (across, along) = if side.is_multiple_of(2) {
            (ch, cw)
        } else {
            (cw, ch)
        };
        let half = frame_of_side.half_profile(across, cfg);
        let k_max = ((2.0 * half / STEP).round() as usize).min(PROFILE - 1);
        // The border's local width across the side at its two ends (perspective changes it),
        // from the cell grid: the distance, along the outward normal, to the grid line one
        // cell in.
        let (rows, cols) = (cells.rows as f64, cells.cols as f64);
        let width_at = |f: f64| -> Option<f64> {
            let (p, q) = match side {
                0 => ((-1.0 + 2.0 * f, -1.0), (-1.0 + 2.0 * f, -1.0 + 2.0 / rows)),
                1 => ((1.0, -1.0 + 2.0 * f), (1.0 - 2.0 / cols, -1.0 + 2.0 * f)),
                2 => ((1.0 - 2.0 * f, 1.0), (1.0 - 2.0 * f, 1.0 - 2.0 / rows)),
                _ => ((-1.0, 1.0 - 2.0 * f), (-1.0 + 2.0 / cols, 1.0 - 2.0 * f)),
            };
            let (p, q) = (frame.map(p.0, p.1)?, frame.map(q.0, q.1)?);
            let w = (p.x - q.x) * n[0] + (p.y - q.y) * n[1];
            (w > 0.0 && w.is_finite()).then_some(w)
        };
        let across_ends = [
            width_at(margin / len).unwrap_or(across),
            width_at(1.0 - margin / len).unwrap_or(across),
        ];
        Some(SideGeom {
            across_ends,
            side,
            a,
            t,
            n,
            len,
            margin,
            count,
            spacing,
            across,
            along,
            half,
            k_max,
        })
    }

    /// Samples the edge profiles of side `g` (appended to `self.profiles`): the median of
    /// their maxima (the quiet zone's level) and the maxima's relative slope along the side
    /// (per half side, in the side's clockwise direction).
    fn sample(&mut self, img: &GrayView<'_>, g: &SideGeom) -> (f64, f64) {
        let mut maxs = [0.0f64; MAX_STATIONS];
        // Sums of the least-squares line of the maxima along the side (u from -1 to 1).
        let (mut s1, mut su, mut suu, mut sv, mut suv) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (s, mx) in maxs.iter_mut().enumerate().take(g.count) {
            let d = g.margin + s as f64 * g.spacing;
            let (px, py) = (g.a[0] + d * g.t[0], g.a[1] + d * g.t[1]);
            let mut prof = [0.0f64; PROFILE];
            sample_profile(
                img,
                [px - g.half * g.n[0], py - g.half * g.n[1]],
                [STEP * g.n[0], STEP * g.n[1]],
                &mut prof[..=g.k_max],
            );
            // Bilinear samples of bytes are never NaN: a plain comparison gives `f64::max`'s
            // answer without its NaN handling in the chain.
            *mx = prof[..=g.k_max]
                .iter()
                .copied()
                .fold(f64::MIN, |m, v| if v > m { v } else { m });
            self.profiles.push(prof);
            let (u, v) = (-1.0 + 2.0 * d / g.len, *mx);
            s1 += 1.0;
            su += u;
            suu += u * u;
            sv += v;
            suv += u * v;
        }
        // Relative slope of the maxima along the side, per half side.
        let den = s1 * suu - su * su;
        let slope = if den > 0.0 && sv > 0.0 {
            (s1 * suv - su * sv) / den / (sv / s1)
        } else {
            0.0
        };
        let m = &mut maxs[..g.count];
        let mid = m.len() / 2;
        let median = *m
            .select_nth_unstable_by(mid, |a: &f64, b: &f64| a.total_cmp(b))
            .1;
        (median, slope)
    }

    /// The edge line of side `g` from its profiles (`self.profiles[first..]`), against the
    /// marker's levels `model` under the light `light` (relative, at normalised marker
    /// coordinates).
    fn side(
        &mut self,
        g: &SideGeom,
        first: usize,
        cells: &Cells,
        model: &LevelModel,
        light: impl Fn(f64, f64) -> f64,
        cfg: &RefineConfig,
    ) -> Option<Line> {
        let (side, half, k_max) = (g.side, g.half, g.k_max);
        let sigma = model.sigma;
        // The rule's reading of the modelled edge, for inner neighbours black (d0) and for the
        // first and second inner cells white (d0 + d1, d0 + d2).
        let bias = |across: f64, w1: f64, w2: f64| -> f64 {
            let mut prof = [0.0f64; PROFILE];
            for (k, v) in prof.iter_mut().enumerate().take(k_max + 1) {
                let x = k as f64 * STEP - half;
                *v = phi(x / sigma)
                    + w1 * (phi((-across - x) / sigma) - phi((-2.0 * across - x) / sigma))
                    + w2 * phi((-2.0 * across - x) / sigma);
            }
            edge_in_profile(&prof[..=k_max], half, 0.0, 1.0).unwrap_or(0.0)
        };
        let d0 = bias(g.across, 0.0, 0.0);
        let ends = g
            .across_ends
            .map(|c| [bias(c, 1.0, 0.0) - d0, bias(c, 0.0, 1.0) - d0]);
        let cells_along = cells.along(side);
        let s_along = sigma / g.along;
        // Whiteness of the inner cell row `depth` at `u` cells along the side.
        let white_at = |depth: usize, u: f64| -> f64 {
            if depth + 1 >= cells.across(side) {
                return 0.0;
            }
            let mut w = 0.0;
            let j0 = (u - 3.0 * s_along - 1.0).max(0.0) as usize;
            let j1 = ((u + 3.0 * s_along + 1.0).ceil() as usize).min(cells_along);
            for j in j0..j1 {
                if !cells.black_from_side(side, depth, j) {
                    w += phi((j as f64 + 1.0 - u) / s_along) - phi((j as f64 - u) / s_along);
                }
            }
            w
        };
        self.pts.clear();
        for (s, prof) in self.profiles[first..].iter().enumerate().take(g.count) {
            let d = g.margin + s as f64 * g.spacing;
            let (px, py) = (g.a[0] + d * g.t[0], g.a[1] + d * g.t[1]);
            let f = d / g.len;
            let (ma, mb) = match side {
                0 => (-1.0 + 2.0 * f, -1.0),
                1 => (1.0, -1.0 + 2.0 * f),
                2 => (1.0 - 2.0 * f, 1.0),
                _ => (-1.0, 1.0 - 2.0 * f),
            };
            let (lo, hi) = (model.lo, model.lo + model.contrast);
            let k = light(ma, mb);
            let (lo, hi) = (lo * k, hi * k);
            // Near a corner the white beyond the adjacent side blurs into the border: the
            // pattern there is the side's own, with its dark part scaled by the share of the
            // blur that falls on the side's length.
            let reach = phi(d / sigma) - phi((d - g.len) / sigma);
            let lo = hi - (hi - lo) * reach;
            if hi - lo < cfg.min_edge_contrast {
                continue;
            }
            let Some(pos) = edge_in_profile(&prof[..=k_max], half, lo, hi) else {
                continue;
            };
            let u = f * cells_along as f64;
            let e = if g.count > 1 {
                s as f64 / (g.count - 1) as f64
            } else {
                0.5
            };
            let d1 = ends[0][0] + (ends[1][0] - ends[0][0]) * e;
            let d2 = ends[0][1] + (ends[1][1] - ends[0][1]) * e;
            let corr = d0 + white_at(1, u) * d1 + white_at(2, u) * d2;
            let pos = pos - corr;
            self.pts.push([px + pos * g.n[0], py + pos * g.n[1], 1.0]);
        }
        if self.pts.len() < 2 || self.pts.len() * 2 < g.count {
            return None;
        }
        fit_line_trimmed(&mut self.pts)
    }
}

/// Where one side's edge profiles are taken.
#[derive(Debug, Clone, Copy)]
struct SideGeom {
    side: usize,
    a: [f64; 2],
    t: [f64; 2],
    n: [f64; 2],
    len: f64,
    margin: f64,
    count: usize,
    spacing: f64,
    across: f64,
    /// The border's width across the side at the first and the last station.
    across_ends: [f64; 2],
    along: f64,
    half: f64,
    k_max: usize,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::Dictionary;
    use proptest::prelude::*;

    fn square(x0: f64, y0: f64, side: f64) -> Corners {
        [
            Point2::new(x0, y0),
            Point2::new(x0 + side, y0),
            Point2::new(x0 + side, y0 + side),
            Point2::new(x0, y0 + side),
        ]
    }

    fn refine_on(pixels: &[u8], w: usize, corners: &Corners) -> Option<Corners> {
        let img = GrayView::new(pixels, w, pixels.len() / w).ok()?;
        let dict = Dictionary::paper();
        let code = dict.code(0)?;
        let cells = Cells::new(dict.family(), code)?;
        PatternRefiner::default().refine(&img, corners, &cells, &RefineConfig::default())
    }

    #[test]
    fn bad_input_keeps_the_plain_corners() {
        let flat = vec![128u8; 80 * 80];
        // No contrast at all: nothing to fit.
        assert_eq!(refine_on(&flat, 80, &square(20.0, 20.0, 35.0)), None);
        // Non-finite corners.
        assert_eq!(refine_on(&flat, 80, &square(f64::NAN, 20.0, 35.0)), None);
        // Cells under a pixel.
        assert_eq!(refine_on(&flat, 80, &square(20.0, 20.0, 5.0)), None);
        // Degenerate quad (all corners on a line).
        let line = [10.0, 30.0, 50.0, 70.0].map(|x| Point2::new(x, 10.0));
        assert_eq!(refine_on(&flat, 80, &line), None);
    }

    proptest! {
        /// Whatever the image and quad, the step never panics and never returns a corner
        /// that is not finite or that moved further than its bound.
        #[test]
        fn output_is_finite_and_near_the_input(
            seed in any::<u64>(),
            x0 in 2.0f64..30.0,
            y0 in 2.0f64..30.0,
            side in 8.0f64..45.0,
            skew in -3.0f64..3.0,
        ) {
            let w = 80usize;
            let pixels = crate::test_bytes(seed, w * w, |_, state| {
                (state >> 56) as u8
            });
            let mut q = square(x0, y0, side);
            q[2][0] += skew;
            q[3][1] -= skew;
            if let Some(out) = refine_on(&pixels, w, &q) {
                // The bound: half a pixel, or a twentieth of the larger cell.
                let limit = 0.5f64.max(0.05 * (side + 3.0) / 6.0) + 1e-9;
                for (c, k) in out.iter().zip(&q) {
                    prop_assert!(c[0].is_finite() && c[1].is_finite());
                    prop_assert!((c[0] - k[0]).hypot(c[1] - k[1]) <= limit);
                }
            }
        }
    }

    #[test]
    fn phi_table_matches_the_formula() {
        let mut worst: f64 = 0.0;
        for k in -10_000..=10_000 {
            let x = k as f64 * 0.001;
            worst = worst.max((phi(x) - normal_cdf(x)).abs());
        }
        assert!(worst < 1e-6, "{worst}");
        assert_eq!(phi(f64::NAN), 0.0);
        assert_eq!(phi(f64::INFINITY), 1.0);
        assert_eq!(phi(-1e300), 0.0);
    }

    #[test]
    fn phi_matches_known_values() {
        assert!((phi(0.0) - 0.5).abs() < 1e-7);
        assert!((phi(1.0) - 0.841_344_746).abs() < 2e-7);
        assert!((phi(-1.959_963_985) - 0.025).abs() < 2e-7);
        assert!(phi(-40.0) >= 0.0 && phi(40.0) <= 1.0);
    }
}
