//! Sub-pixel corner refinement by fitting lines to the grey-level edges (spec 3.4, step 3,
//! "beyond").
//!
//! The coarse corners from the contour are pixel centres of the outermost dark pixels, so
//! they are off by up to a pixel. Each side of the quadrilateral is refined on the grey image
//! (never on the binary one): at regular stations along the side (away from the corners,
//! which blur rounds off) the grey profile across the edge is sampled bilinearly every half
//! pixel. A station's dark and light levels are low percentiles of the profiles' minima and
//! maxima over each half of the side, interpolated along it; the edge is first located where the profile crosses their midpoint, then by the
//! area under the normalised profile over a window centred there, which is exact for any
//! symmetric blur and for unblurred, area-sampled edges (the plain crossing of interpolated
//! samples is pulled towards pixel centres by up to a tenth of a pixel). A total-least-squares line is fitted to the
//! edge points of each side, points far off the line are dropped and the line refitted; the
//! corners are the intersections of adjacent lines. The whole is done twice, the second
//! time with stations placed on the refined lines so the profiles are centred on the edge.

use crate::image::{Corners, GrayView};
use crate::quad::convex_clockwise;
use nalgebra::Point2;

/// Settings of the refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineConfig {
    /// Stations closer than this fraction of the side length to a corner are skipped.
    pub corner_margin_rel: f64,
    /// ...and closer than this many pixels.
    pub corner_margin_px: f64,
    /// Smallest grey-level step (max - min of a profile) that counts as an edge.
    pub min_edge_contrast: f64,
    /// Largest number of stations per side.
    pub max_stations: usize,
    /// Spacing of stations along a side, in pixels.
    pub station_spacing: f64,
    /// Largest half-length of an edge profile (second pass), in pixels.
    pub max_half_profile: f64,
    /// Largest half-length of an edge profile (second pass) as a fraction of the estimated
    /// border-cell width across the side (the quadrilateral's depth across the side divided
    /// by the marker's cells across), so that a profile stays inside the one-cell border and,
    /// on a marker with a quiet zone of one cell, inside that zone: blur from whatever lies
    /// beyond them shifts the levels the edge is measured against. The floor of 1.5 px
    /// still applies.
    pub max_half_profile_cells: f64,
    /// Refine each decoded marker's corners once more against its known cell pattern
    /// (default on): levels and blur fitted over all of its cells, edges corrected for the
    /// blur of their inner neighbours and of the adjacent sides. On the accuracy scenes it
    /// halves the corner error of 20-40 px markers (`crate::pattern` explains the model).
    pub with_pattern: bool,
    /// Fit the corners of decoded markers whose cells are smaller than this many pixels
    /// (along the narrower axis) to the marker's whole modelled image: its cells, a one-cell
    /// white quiet zone and one surround level per side beyond it, under a fitted Gaussian
    /// blur (`crate::photometric` explains the model). The edge rules place every side of
    /// such a marker inwards when what lies beyond the quiet zone is darker (0.07-0.12 px
    /// per corner at 2-3 px cells under a 1 px blur, and up to 0.3-1 px on faces seen 45-65
    /// degrees off axis), which put the `far` scenario's `l12` 12.8 mm long; fitted, its
    /// `l12` error is -0.2 to +0.2 mm. It costs about 0.5-2 ms per marker fitted, which on
    /// real frames with many small tags doubles the detection time, for no gain measured
    /// there (`docs/performance.md`). Default 0, off; [`crate::DetectorConfig::for_pose`]
    /// sets [`PHOTOMETRIC_BELOW_PX`].
    pub photometric_below_px: f64,
}

impl Default for RefineConfig {
    /// Stations at least 8 % of the side (and 2 px) from the corners, one per pixel up to
    /// 64 per side, edges of at least 10 grey levels, profiles of at most +-2.5 px and at
    /// most +-0.4 border cell (a longer profile on a small blurred marker reaches the blur of
    /// what lies beyond the border cell or the quiet zone: with a one-cell quiet zone against
    /// a black surround, markers 24 px wide under blur sigma 1 px read 0.136 px small per side
    /// with 2.5 px profiles and 0.094 px with the bound; against a surround as light as the
    /// quiet zone both are within 0.011 px). 64
    /// stations and the 8 % margin (rather than 32 and 12 %) keep every single corner
    /// within 0.1 px of the truth for markers of 40-160 px under noise sigma 3 and blur up to
    /// 1 (no case over 0.1 px in 6000 seeded views; 32 stations left about 1 in 3000 over).
    fn default() -> Self {
        Self {
            corner_margin_rel: 0.08,
            corner_margin_px: 2.0,
            min_edge_contrast: 10.0,
            max_stations: 64,
            station_spacing: 1.0,
            max_half_profile: 2.5,
            max_half_profile_cells: 0.4,
            with_pattern: true,
            photometric_below_px: 0.0,
        }
    }
}

/// The cell size under which [`crate::DetectorConfig::for_pose`] fits a marker's corners
/// to its whole modelled image ([`RefineConfig::photometric_below_px`]), pixels: the edge
/// rules' bias is largest at 2-3 px cells (0.07-0.12 px per corner, more on oblique faces);
/// larger cells gain less for the same cost (fitting up to 8 px halves the face-on corner
/// error of the rig at 2.5-3.8 m, 0.026-0.044 px to 0.014 px, at 1-2 ms more a marker;
/// `docs/tracking.md`).
pub const PHOTOMETRIC_BELOW_PX: f64 = 3.0;

/// Bilinear grey level at `(x, y)` (pixel-centre convention), clamped to the frame.
#[inline]
pub fn bilinear(img: &GrayView<'_>, x: f64, y: f64) -> f64 {
    if img.within(x, y) {
        // Nothing to clamp (the same value).
        return bilinear_inside(img, x, y);
    }
    // Clamped to >= 0, so truncation is floor (and NaN becomes 0); a signed cast is one
    // instruction, an unsigned one several.
    let x = x.max(0.0).min(img.max_x());
    let y = y.max(0.0).min(img.max_y());
    let (xi, yi) = (x as i64, y as i64);
    let fx = x - xi as f64;
    let fy = y - yi as f64;
    let (xi, yi) = (xi as usize, yi as usize);
    let xj = (xi + 1).min(img.width() - 1);
    let r0 = img.row(yi);
    let r1 = img.row((yi + 1).min(img.height() - 1));
    let top = f64::from(r0[xi]) + (f64::from(r0[xj]) - f64::from(r0[xi])) * fx;
    let bot = f64::from(r1[xi]) + (f64::from(r1[xj]) - f64::from(r1[xi])) * fx;
    top + (bot - top) * fy
}

/// Samples `out.len()` bilinear grey levels at `start + k * step`. When the whole segment
/// lies inside the frame the samples are read without clamping.
pub(crate) fn sample_profile(img: &GrayView<'_>, start: [f64; 2], step: [f64; 2], out: &mut [f64]) {
    let last = (out.len().max(1) - 1) as f64;
    let end = [start[0] + last * step[0], start[1] + last * step[1]];
    if !(img.within(start[0], start[1]) && img.within(end[0], end[1])) {
        for (k, v) in out.iter_mut().enumerate() {
            let t = k as f64;
            *v = bilinear(img, start[0] + t * step[0], start[1] + t * step[1]);
        }
        return;
    }
    let mut t = 0.0;
    for v in out.iter_mut() {
        *v = bilinear_inside(img, start[0] + t * step[0], start[1] + t * step[1]);
        t += 1.0;
    }
}

/// [`bilinear`] at a point of `[0, width - 1) x [0, height - 1)`, where it needs no
/// clamping (the same value).
#[inline]
pub(crate) fn bilinear_inside(img: &GrayView<'_>, x: f64, y: f64) -> f64 {
    // Non-negative, so truncation is floor; signed casts are single instructions.
    let (xi, yi) = (x as i64, y as i64);
    let (fx, fy) = (x - xi as f64, y - yi as f64);
    let [a, b, c, d] = img.square(xi as usize, yi as usize).map(f64::from);
    let top = a + (b - a) * fx;
    let bot = c + (d - c) * fx;
    top + (bot - top) * fy
}

/// Refines an edge position `pos` (profile coordinates: sample `k` is at `k * step - half`)
/// by the area method: over a window of one pixel either side of `pos`, the edge lies at the
/// window start plus the integral of the normalised darkness `1 - (g - lo) / (hi - lo)` of
/// the piecewise-linear profile. For a symmetric edge profile an error `e` in `pos` becomes
/// `2 e t`, where `t` is the profile's tail mass beyond the window, and the area-sampled step
/// of an unblurred edge is located exactly, whereas the midpoint crossing of interpolated
/// samples is off by up to an eighth of a pixel on sharp edges. `None` if the window would
/// leave the profile.
fn area_edge(prof: &[f64], step: f64, half: f64, pos: f64, lo: f64, hi: f64) -> Option<f64> {
    let span = (prof.len() - 1) as f64 * step;
    let w = (pos + half).min(span - (pos + half)).min(1.0);
    if w < 0.999 || hi.is_nan() || lo.is_nan() || hi <= lo {
        return None;
    }
    // Window [a, b] in sample units.
    let a = (pos + half - w) / step;
    let b = (pos + half + w) / step;
    let inv = 1.0 / (hi - lo);
    let dark = |g: f64| 1.0 - ((g - lo) * inv).clamp(0.0, 1.0);
    let at = |t: f64| -> f64 {
        let k = (t as i64).min(prof.len() as i64 - 2);
        let f = t - k as f64;
        let k = k as usize;
        prof[k] + (prof[k + 1] - prof[k]) * f
    };
    // Trapezoids over [a, b], split at sample points (the profile is linear between them).
    let mut sum = 0.0;
    let mut t0 = a;
    // The darkness at t0, carried over from the previous trapezoid's end.
    let mut d0 = dark(at(t0));
    // The sample after t0: a >= 0 (the window starts inside the profile), so truncation is
    // floor; without SSE4.1 a cast costs a fraction of `floor`'s software call, and a
    // signed one a fraction of an unsigned one. After the first trapezoid t0 is a sample.
    let mut k1 = a as i64 + 1;
    let last = (prof.len() - 1) as i64;
    while t0 < b - 1e-12 {
        let t1 = (k1 as f64).min(b);
        // At a sample inside the profile the interpolation is the sample itself.
        let d1 = if t1 < b && k1 < last {
            dark(prof[k1 as usize])
        } else {
            dark(at(t1))
        };
        sum += 0.5 * (d0 + d1) * (t1 - t0);
        (t0, d0) = (t1, d1);
        k1 += 1;
    }
    Some(pos - w + sum * step)
}

/// A line `n . p = c` with unit normal `n`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line {
    pub(crate) n: [f64; 2],
    pub(crate) c: f64,
}

pub(crate) fn intersect(a: &Line, b: &Line) -> Option<[f64; 2]> {
    let det = a.n[0] * b.n[1] - a.n[1] * b.n[0];
    if det.abs() < 1e-9 {
        return None;
    }
    let x = (a.c * b.n[1] - b.c * a.n[1]) / det;
    let y = (a.n[0] * b.c - b.n[0] * a.c) / det;
    (x.is_finite() && y.is_finite()).then_some([x, y])
}

/// Fits a line to `pts`, drops the points more than 0.75 px off it and refits (`None` when
/// fewer than two remain).
pub(crate) fn fit_line_trimmed(pts: &mut Vec<[f64; 3]>) -> Option<Line> {
    let line = fit_line(pts)?;
    let tol = 0.75;
    pts.retain(|p| (line.n[0] * p[0] + line.n[1] * p[1] - line.c).abs() <= tol);
    if pts.len() < 2 {
        return None;
    }
    fit_line(pts)
}

/// Weighted total-least-squares line through points `(x, y, w)`.
pub(crate) fn fit_line(pts: &[[f64; 3]]) -> Option<Line> {
    let sw: f64 = pts.iter().map(|p| p[2]).sum();
    if pts.len() < 2 || sw.is_nan() || sw <= 0.0 {
        return None;
    }
    let mx = pts.iter().map(|p| p[0] * p[2]).sum::<f64>() / sw;
    let my = pts.iter().map(|p| p[1] * p[2]).sum::<f64>() / sw;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += p[2] * dx * dx;
        sxy += p[2] * dx * dy;
        syy += p[2] * dy * dy;
    }
    // Direction of largest spread: angle of the principal axis.
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let n = [-theta.sin(), theta.cos()];
    let c = n[0] * mx + n[1] * my;
    c.is_finite().then_some(Line { n, c })
}

/// Scratch space of the refinement (edge points of one side).
#[derive(Debug, Default, Clone)]
pub struct Refiner {
    pts: Vec<[f64; 3]>,
    profiles: Vec<([f64; 2], [f64; PROFILE])>,
}

/// Most samples in one edge profile.
pub(crate) const PROFILE: usize = 16;

impl Refiner {
    /// An empty refiner.
    pub fn new() -> Self {
        Self::default()
    }

    /// Refines clockwise coarse corners (pixel centres of the outermost dark pixels). Returns
    /// the refined corners and the mean edge contrast (grey levels), or `None` if an edge
    /// cannot be found or the refined quadrilateral is implausible. `cells_across` is the
    /// marker's width in cells, border included (the larger of its two sides); it bounds
    /// the edge profiles through [`RefineConfig::max_half_profile_cells`].
    pub fn refine(
        &mut self,
        img: &GrayView<'_>,
        coarse: &Corners,
        cfg: &RefineConfig,
        min_angle_deg: f64,
        cells_across: f64,
    ) -> Option<(Corners, f64)> {
        let mut corners = *coarse;
        let mut contrast = 0.0;
        // First pass: the true edge lies about half a pixel outside the dark pixel centres.
        for pass in [0, 1] {
            let mut lines = [Line {
                n: [0.0, 0.0],
                c: 0.0,
            }; 4];
            let mut csum = 0.0;
            for (i, line) in lines.iter_mut().enumerate() {
                let (a, b) = (corners[i], corners[(i + 1) % 4]);
                // The marker's depth across this side: the nearer of the two opposite
                // corners' distances to the side's line; a border cell is that over the
                // cells across (conservative for the shorter dimension of the marker).
                let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
                let len = dx.hypot(dy);
                let depth = [corners[(i + 2) % 4], corners[(i + 3) % 4]]
                    .iter()
                    .map(|p| ((p[0] - a[0]) * dy - (p[1] - a[1]) * dx).abs() / len)
                    .fold(f64::INFINITY, f64::min);
                let cell = depth / cells_across.max(1.0);
                let (l, c) = self.side(img, a.into(), b.into(), pass, cell, cfg)?;
                *line = l;
                csum += c;
            }
            contrast = csum / 4.0;
            let mut next = [Point2::origin(); 4];
            for (i, corner) in next.iter_mut().enumerate() {
                *corner = intersect(&lines[(i + 3) % 4], &lines[i])?.into();
            }
            corners = next;
        }
        // Plausibility: close to the coarse corners, inside the frame, still convex.
        let w = img.width() as f64;
        let h = img.height() as f64;
        // Blur and the threshold blunt sharp corners, so the coarse corner may sit a few
        // pixels inside the true one on large markers.
        let mean_side = (0..4)
            .map(|i| {
                let (p, q) = (coarse[i], coarse[(i + 1) % 4]);
                (p[0] - q[0]).hypot(p[1] - q[1])
            })
            .sum::<f64>()
            / 4.0;
        let limit = 3.0 + 0.05 * mean_side;
        for (c, k) in corners.iter().zip(coarse) {
            let moved = (k[0] - c[0]).hypot(k[1] - c[1]);
            if moved.is_nan()
                || moved > limit
                || c[0] < -0.5
                || c[1] < -0.5
                || c[0] > w - 0.5
                || c[1] > h - 0.5
            {
                return None;
            }
        }
        convex_clockwise(&corners, min_angle_deg).then_some((corners, contrast))
    }

    /// Fits the edge line of the side from `a` to `b` (clockwise, so the outside is on the
    /// left of the direction of travel in the image).
    fn side(
        &mut self,
        img: &GrayView<'_>,
        a: [f64; 2],
        b: [f64; 2],
        pass: usize,
        cell: f64,
        cfg: &RefineConfig,
    ) -> Option<(Line, f64)> {
        let st = Stations::new(a, b, pass, cell, cfg)?;
        let (mins, maxs) = self.sample_profiles(img, &st, pass);
        let m = st.count.min(MAX_LEVELS);
        let levels = Levels::new(&mins[..m], &maxs[..m]);
        let mut csum = 0.0;
        self.pts.clear();
        for (i, ([px, py], prof)) in self.profiles.iter().enumerate().take(m) {
            let (lo, hi) = levels.at(i);
            if hi - lo < cfg.min_edge_contrast {
                continue;
            }
            csum += hi - lo;
            if let Some(pos) = edge_in_profile(&prof[..=st.k_max], st.half, lo, hi) {
                self.pts.push([px + pos * st.n[0], py + pos * st.n[1], 1.0]);
            }
        }
        let contrast = csum / self.pts.len().max(1) as f64;
        if self.pts.len() < 2 || self.pts.len() * 2 < st.count {
            return None;
        }
        Some((self.fit_without_outliers()?, contrast))
    }

    /// Samples the edge profile of every station (into `self.profiles`) and returns each
    /// profile's minimum and negated maximum, for the first [`MAX_LEVELS`] stations.
    fn sample_profiles(
        &mut self,
        img: &GrayView<'_>,
        st: &Stations,
        pass: usize,
    ) -> ([f64; MAX_LEVELS], [f64; MAX_LEVELS]) {
        self.profiles.clear();
        let mut mins = [0.0f64; MAX_LEVELS];
        let mut maxs = [0.0f64; MAX_LEVELS];
        // The first pass starts from the coarse corners, whose true edge lies about half a
        // pixel outside the dark pixel centres; the second from the refined lines.
        let offset = if pass == 0 { 0.5 } else { 0.0 };
        let (t, n) = (st.t, st.n);
        for s in 0..st.count {
            let d = st.margin + s as f64 * st.spacing;
            let px = st.a[0] + d * t[0] + offset * n[0];
            let py = st.a[1] + d * t[1] + offset * n[1];
            let mut prof = [0.0f64; PROFILE];
            sample_profile(
                img,
                [px - st.half * n[0], py - st.half * n[1]],
                [STEP * n[0], STEP * n[1]],
                &mut prof[..=st.k_max],
            );
            // Bilinear samples of bytes are never NaN, so plain comparisons give what
            // `f64::min` and `max` would, without their NaN handling in the chain.
            let (mut plo, mut phi) = (f64::MAX, f64::MIN);
            for &v in &prof[..=st.k_max] {
                if v < plo {
                    plo = v;
                }
                if v > phi {
                    phi = v;
                }
            }
            if s < MAX_LEVELS {
                mins[s] = plo;
                maxs[s] = -phi;
            }
            self.profiles.push(([px, py], prof));
        }
        (mins, maxs)
    }

    /// Fits a line to `self.pts`, drops the points more than 0.75 px off it and refits.
    fn fit_without_outliers(&mut self) -> Option<Line> {
        fit_line_trimmed(&mut self.pts)
    }
}

/// Spacing of the samples of an edge profile, pixels.
pub(crate) const STEP: f64 = 0.5;

/// Stations whose profile minima and maxima set the edge levels (the rest are sampled too).
const MAX_LEVELS: usize = 64;

/// Where the edge profiles of one side are taken.
#[derive(Debug, Clone, Copy)]
struct Stations {
    /// The side's start.
    a: [f64; 2],
    /// Unit direction along the side.
    t: [f64; 2],
    /// Unit outward normal.
    n: [f64; 2],
    /// Distance of the first station from `a`.
    margin: f64,
    /// Number of stations.
    count: usize,
    /// Distance between stations.
    spacing: f64,
    /// Half-length of a profile, pixels.
    half: f64,
    /// Index of a profile's last sample.
    k_max: usize,
}

/// A side `a -> b` as its edge profiles see it (the plain refinement's and
/// [`crate::pattern`]'s): its length, unit tangent and outward normal, the margin kept from
/// each corner, and the length left between the margins.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SideFrame {
    pub(crate) len: f64,
    pub(crate) t: [f64; 2],
    pub(crate) n: [f64; 2],
    pub(crate) margin: f64,
    pub(crate) usable: f64,
}

impl SideFrame {
    /// `None` for a side too short to have stations between its margins.
    pub(crate) fn new(a: [f64; 2], b: [f64; 2], cfg: &RefineConfig) -> Option<Self> {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = (dx * dx + dy * dy).sqrt();
        if len.is_nan() || len <= 2.0 {
            return None;
        }
        let t = [dx / len, dy / len];
        let n = [t[1], -t[0]]; // outward
        let margin = (cfg.corner_margin_rel * len).max(cfg.corner_margin_px);
        let usable = len - 2.0 * margin;
        if usable <= 0.0 {
            return None;
        }
        Some(Self {
            len,
            t,
            n,
            margin,
            usable,
        })
    }

    /// Half-length of a refining profile across a border `cell` pixels wide: wide enough
    /// for blur, short enough to stay inside the border cell on small markers (`min`
    /// ignores a NaN cell width, `max` a NaN cap).
    pub(crate) fn half_profile(&self, cell: f64, cfg: &RefineConfig) -> f64 {
        let cap = cfg
            .max_half_profile
            .min(cfg.max_half_profile_cells * cell)
            .max(1.5);
        (0.1 * self.len).clamp(1.5, cap)
    }
}

impl Stations {
    /// Stations along the side `a -> b` for refinement pass `pass`, with `cell` the estimated
    /// border-cell width across it; `None` for a side too short to have any.
    fn new(a: [f64; 2], b: [f64; 2], pass: usize, cell: f64, cfg: &RefineConfig) -> Option<Self> {
        let side = SideFrame::new(a, b, cfg)?;
        let SideFrame {
            len,
            t,
            n,
            margin,
            usable,
        } = side;
        // The first pass only has to centre the second: a few stations suffice.
        let cap = if pass == 0 {
            8
        } else {
            cfg.max_stations.max(2)
        };
        let count = ((usable / cfg.station_spacing.max(0.5)) as usize + 1).clamp(2, cap);
        let spacing = usable / (count - 1) as f64;
        // Half-width of the profile: the first pass only has to find the edge.
        let half = if pass == 0 {
            (0.12 * len).clamp(1.5, 3.5)
        } else {
            side.half_profile(cell, cfg)
        };
        let k_max = ((2.0 * half / STEP).round() as usize).min(PROFILE - 1);
        Some(Self {
            a,
            t,
            n,
            margin,
            count,
            spacing,
            half,
            k_max,
        })
    }
}

/// The value of rank `len / 10` (0-based, in `f64::total_cmp` order) of at most
/// [`MAX_LEVELS`] values: the low percentile the levels are taken at. The few smallest are
/// kept sorted in a small array, which costs far less than a selection over the copy of all.
fn tenth(v: &[f64]) -> f64 {
    let rank = v.len() / 10;
    let mut low = [f64::INFINITY; MAX_LEVELS / 10 + 1];
    let low = &mut low[..=rank];
    for (i, &x) in v.iter().enumerate() {
        // Insert x among the `rank + 1` smallest so far (the last one drops out).
        let mut j = i.min(rank);
        if i > rank && x.total_cmp(&low[rank]).is_ge() {
            continue;
        }
        while j > 0 && x.total_cmp(&low[j - 1]).is_lt() {
            low[j] = low[j - 1];
            j -= 1;
        }
        low[j] = x;
    }
    low[rank]
}

/// The dark and light levels of each station of a side.
///
/// Stations next to a white data cell see a dark level lifted by blur (on small markers),
/// stations next to a black one see the true dark, so a low percentile of the minima over the
/// whole side is the border's own level; noise pushes minima and maxima alike, so their
/// midpoint stays unbiased. Lighting may vary along the side: the light level (the quiet
/// zone, never contaminated) is taken over each half of the side and interpolated linearly,
/// and the dark level scales with it (reflectance times light).
#[derive(Debug, Clone, Copy)]
struct Levels {
    lo_all: f64,
    hi_all: f64,
    hi_a: f64,
    hi_b: f64,
    /// Station positions (fractional indices) where the light level is `hi_a`, `hi_b`.
    c_a: f64,
    c_b: f64,
}

impl Levels {
    /// From the profile minima (reordered in place) and negated maxima of the stations.
    fn new(mins: &[f64], maxs: &[f64]) -> Self {
        let m = mins.len();
        let lo_all = tenth(mins);
        let hi_all = -tenth(maxs);
        let half_m = m / 2;
        let (hi_a, hi_b, c_a, c_b) = if m >= 6 {
            let (ha, hb) = (-tenth(&maxs[..half_m]), -tenth(&maxs[half_m..m]));
            // Only a clear gradient (over 8 % along the side) is followed; otherwise the
            // whole side's levels are steadier.
            if (ha - hb).abs() > 0.08 * hi_all {
                (
                    ha,
                    hb,
                    (half_m as f64 - 1.0) / 2.0,
                    half_m as f64 + ((m - half_m) as f64 - 1.0) / 2.0,
                )
            } else {
                (hi_all, hi_all, 0.0, 1.0)
            }
        } else {
            (hi_all, hi_all, 0.0, 1.0)
        };
        Self {
            lo_all,
            hi_all,
            hi_a,
            hi_b,
            c_a,
            c_b,
        }
    }

    /// `(dark, light)` at station `i`.
    fn at(&self, i: usize) -> (f64, f64) {
        let t = (i as f64 - self.c_a) / (self.c_b - self.c_a);
        let hi = self.hi_a + (self.hi_b - self.hi_a) * t;
        let lo = if self.hi_all > 0.0 {
            self.lo_all * hi / self.hi_all
        } else {
            self.lo_all
        };
        (lo, hi)
    }
}

/// The edge in a profile of samples `STEP` apart centred on its station (sample `k` at
/// `k * STEP - half`): the upward crossing of the levels' midpoint nearest the centre, refined
/// by the area method; `None` without a crossing.
pub(crate) fn edge_in_profile(prof: &[f64], half: f64, lo: f64, hi: f64) -> Option<f64> {
    let mid = 0.5 * (lo + hi);
    let mut best: Option<f64> = None;
    let mut kf = 0.0;
    for pair in prof.windows(2) {
        let (g0, g1) = (pair[0], pair[1]);
        if g0 < mid && g1 >= mid {
            let pos = (kf + (mid - g0) / (g1 - g0)) * STEP - half;
            if best.is_none_or(|p| pos.abs() < p.abs()) {
                best = Some(pos);
            }
        }
        kf += 1.0;
    }
    // The crossing of interpolated samples is biased by up to a tenth of a pixel depending
    // on the edge's phase against the pixel grid ("pixel locking"); the area over a window
    // centred on it is not, and shrinks its error.
    best.map(|pos| area_edge(prof, STEP, half, pos, lo, hi).unwrap_or(pos))
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        /// The levels' percentile is the value of rank `len / 10` of the sorted values.
        #[test]
        fn tenth_is_the_rank_of_a_tenth(
            v in proptest::collection::vec(-300.0f64..300.0, 1..=MAX_LEVELS),
            repeat in 0usize..4,
        ) {
            // Repeated values too, as flat profiles give.
            let mut v = v;
            let n = v.len();
            for i in 0..n.min(repeat * 5) {
                v[i] = v[i / 3];
            }
            let mut sorted = v.clone();
            sorted.sort_by(f64::total_cmp);
            proptest::prop_assert_eq!(tenth(&v).to_bits(), sorted[n / 10].to_bits());
        }
    }

    #[test]
    fn line_fit_and_intersection() {
        let pts: Vec<[f64; 3]> = (0..10)
            .map(|i| [i as f64, 2.0 * i as f64 + 1.0, 1.0])
            .collect();
        let l = fit_line(&pts).unwrap();
        for p in &pts {
            assert!((l.n[0] * p[0] + l.n[1] * p[1] - l.c).abs() < 1e-9);
        }
        let h = Line {
            n: [0.0, 1.0],
            c: 5.0,
        };
        let x = intersect(&l, &h).unwrap();
        assert!((x[0] - 2.0).abs() < 1e-9 && (x[1] - 5.0).abs() < 1e-9);
        assert!(intersect(&h, &h).is_none());
    }

    #[test]
    fn bilinear_is_clamped_and_exact_at_centres() {
        let data = [0u8, 100, 200, 50];
        let img = GrayView::new(&data, 2, 2).unwrap();
        assert_eq!(bilinear(&img, 1.0, 0.0), 100.0);
        assert_eq!(bilinear(&img, 0.5, 0.0), 50.0);
        assert_eq!(bilinear(&img, -5.0, 9.0), 200.0);
        assert_eq!(bilinear(&img, f64::NAN, 0.0), 0.0);
    }
}
