//! The side check (issue #16): is a decoded quad the marker's outline, or does a side run
//! along something in front of the marker?
//!
//! When an occluder lighter than the border covers a strip of a marker along one side, the
//! dark region the detector outlines ends at the occluder's edge: that side of the quad lies
//! inside the marker, the two corners on it slide along the neighbouring sides, and the grid
//! may still read the right code (the cells are only squeezed by a fraction of a cell), so
//! the corners reach the pose wrong by the width of the strip. What gives such a quad away is
//! the *inner* edge of the black border: the quad's projective grid puts it one cell inside
//! every side, and on a real outline it is there; on a side cut by an occluder it is closer
//! to the side than the squeezed grid says, by nearly the width of the strip.
//!
//! With the code known after decoding, the check knows where a light data cell touches the
//! border. For each such cell it samples the grey profile across the border, along the
//! cell's centre line (three parallel lines, averaged), from the middle of the border cell
//! to the middle of the data cell, and finds where it crosses the mean of its two ends: the
//! border's inner edge, which a symmetric blur does not move. The offset of that crossing
//! from the grid's prediction, in pixels across the side (perpendicular to it, as the outer
//! edges are measured: on a sheared quad the grid's line through a cell meets the side at a
//! slant), is taken per side as the median over its cells.
//! A side whose median offset (border thinner than the grid says) is larger than [`SideCheck::tolerance_px`] (plus
//! [`SideCheck::tolerance_cells`] of a cell, plus [`SideCheck::tolerance_motion`] of the
//! motion blur across the side) is not the marker's side, and the marker is dropped. A side
//! with no light data cell next to it, or whose profiles are too flat (a heavily blurred
//! marker), gives no evidence and passes.
//!
//! A corner cut off by an occluder (its edge crossing the two sides that meet there) moves
//! only the cells next to that corner, which a median per side does not see. Two more
//! measurements catch it, both against what a whole marker must show:
//! - **The corner's border cell** ([`SideOffsets::corner_level`]): where the fitted sides
//!   still meet near the hidden corner, the grid's corner cell lies on the occluder and reads
//!   light, while a border cell is dark. Allowed: [`SideCheck::corner_tolerance`] of the
//!   contrast, plus the light that the optical and motion blur bring in from outside. The
//!   level is taken above the border's own black near that corner: where glare or shading
//!   lights a whole border unevenly, the corner's two neighbouring border cells and some
//!   cell of the far sides are lit as well, which a corner cut does not do (the median is
//!   raised by the smaller of those two excesses; on 1,500 rendered corner cuts by light
//!   boards of markers 36-90 px wide, as many passed with it as without, 165, of which as
//!   many, 42, were more than 0.5 px + 0.08 cell off).
//! - **The outer edge near the corner** ([`SideOffsets::outer_inset_px`]): where the occluder
//!   meets a side at a shallow angle, the fitted side follows it part of the way and the
//!   corner slides inwards, so the corner cell stays dark; but the outline there (the
//!   occluder's edge) lies inside the quad. Only that direction counts, since a real marker
//!   may touch something as dark as its border; allowed: [`SideCheck::outer_tolerance_px`]
//!   plus the blur, plus the bow that lens distortion puts into long sides
//!   ([`SideCheck::outer_sag_per_px2`]).
//!
//! On 940 rendered corner cuts of faces 14-55 px wide (the formation scenes, four seeds),
//! the three checks drop 83-86 % (the side check alone: 11-13 %); the deepest cut that
//! passed hid its corner 3.1 px deep, and its corners were at most 1.9 px off. Of the 907
//! whole faces in the same scenes and the 56 tags of the real Duckietown frames, none was
//! dropped. What remains (`tests/side_check.rs`):
//! - a board whose edge runs along a side at a slant, cutting the corner at one end, where
//!   every data cell next to that side is dark: the side gives no inner-edge evidence, the
//!   quad's side runs along the board's edge, and the corner slides to where that edge
//!   meets the next side, its border cell still dark (on markers of 36-90 px, corners up to
//!   12 px off, never further than the board hides the corner);
//! - a dark grey board (about 0.2 of the contrast above the border) is under
//!   [`SideCheck::min_step`] for the outer-edge check;
//! - on markers over about 70 px the lens allowance lets a corner sliced off along a side
//!   pass, no further off than the cut is deep.
//!
//! Last, a quad none of whose sides shows a light outside is not a marker's outline
//! ([`SideOffsets::outside_step`]): some side must show the step from the light outside to
//! the dark border, of at least [`SideCheck::min_outside_step`] of the contrast. A marker
//! lies on paper as light as its light cells; it may touch something as dark as its border
//! along a side or two (the quads boundary clustering finds), not all round. Issue #31: on
//! `board.jpg` of OpenCV's samples, a dark blob 13 px across with a highlight inside it,
//! on grey, read as a 4 x 4 code (boundary clustering found its quad) whose light cells
//! were the highlight, far lighter than the grey around the blob. The other checks had no
//! evidence there (cells under [`SideCheck::min_cell_px`], no outer profile over
//! [`SideCheck::min_step`]); its largest step was 0.37 of its contrast, where every marker
//! read on the real frames (Duckietown, NASA, OpenCV's ArUco photo) shows 1.03 or more and
//! every quad decoded in the crate's synthetic tests 0.8 or more.
//!
//! No allocation: every buffer is a fixed array.

use crate::cross_ratio::CrossRatioFrame;
use crate::decode::Decoded;
use crate::family::MarkerFamily;
use crate::image::GrayView;
use crate::refine::{bilinear, bilinear_inside};

/// Settings of the side check ([`crate::DetectorConfig::side_check`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideCheck {
    /// Largest offset of a side's inner border edge from where the grid puts it, in pixels
    /// (default 0.35).
    pub tolerance_px: f64,
    /// ...plus this fraction of the local cell width (default 0.06): on real frames (lens
    /// distortion, print) whole tags' inner edges lie up to 0.12 cell from the grid of
    /// their four corners (two of the 51 Duckietown tags the detector reads were dropped
    /// without it). A cut moves the inner edge by about 0.85 of its width, so corners of a
    /// marker that passes are within about 0.45 px + 0.07 cell of the truth...
    pub tolerance_cells: f64,
    /// ...plus this fraction of the marker's motion blur (default 0.5): the smear measured
    /// from how slowly the border's edges rise (25 % to 75 % of the step, slowest side)
    /// beyond an edge under the optical blur alone, the smaller of the inner edges' and the
    /// outer edges' figure (a grid read one corner round makes the inner profiles rise
    /// slowly with no smear at all; the outer edges are the quad's own sides): the refined
    /// corners of a smeared marker are off by a fraction of the smear.
    pub tolerance_motion: f64,
    /// A profile counts only when its two ends differ by at least this fraction of the
    /// marker's contrast (default 0.4).
    pub min_step: f64,
    /// A profile counts only where a cell is at least this many pixels across the side
    /// (default 2): on narrower cells (a face seen 70 deg or more off-axis) the blur of
    /// the outer edge and of the next cell reach the inner edge, which then wanders by more
    /// than the tolerance on whole markers. From 2 px on it does not: on 200 rendered
    /// scenes (blur 1 px, noise 3), whole markers' sides of 2-3 px cells were off by at most
    /// 0.29 px against a tolerance of 0.47-0.53 px, while a gate at 3 px let faces of 2.3-2.9
    /// px cells cut 1-1.5 px deep through unchecked (the CI failure of 2026-11-24: a 1.5 px
    /// cut of a 21.5 px face, 2.9 px cells, used alone).
    pub min_cell_px: f64,
    /// Largest grey level of a corner's border cell, as a fraction of the marker's contrast
    /// above its border's black (default 0.35): a cell the quad's grid puts at a corner of
    /// the border but that reads light is not the marker's corner (see [`SideOffsets`]).
    pub corner_tolerance: f64,
    /// How far the border's outer edge may lie inside a side of the quad, in pixels
    /// (default 0.5), plus the allowances of [`SideOffsets::outer_tolerance_px`].
    pub outer_tolerance_px: f64,
    /// Smallest step from the light outside a side to the dark border, as a fraction of the
    /// marker's contrast, that some side of the marker must show (default 0.5; see
    /// [`SideOffsets::outside_step`]).
    pub min_outside_step: f64,
    /// The allowance for lens distortion in that check, per squared pixel of the side's
    /// length (default 2e-4): radial distortion bows a straight edge by a sagitta that grows
    /// with the square of its length, and the quad's side is its chord, so the ends of a
    /// long side lie inside the bowed edge. On the real Duckietown frames (a wide-angle lens,
    /// not undistorted) a 95 px tag's side bows by 2 px.
    pub outer_sag_per_px2: f64,
}

impl Default for SideCheck {
    /// The defaults documented on each field.
    fn default() -> Self {
        Self {
            tolerance_px: 0.35,
            tolerance_cells: 0.06,
            tolerance_motion: 0.5,
            min_cell_px: 2.0,
            min_step: 0.4,
            corner_tolerance: 0.35,
            outer_tolerance_px: 0.5,
            outer_sag_per_px2: 2e-4,
            min_outside_step: 0.5,
        }
    }
}

/// Most cells along one side (a 10 x 10 marker has 8 data cells per side).
const MAX_CELLS: usize = 16;
/// Samples per profile, from 0.2 cell inside the side to 0.6 cell past the border's inner
/// edge (a border squeezed by a cut still has dark samples at the start).
const SAMPLES: usize = 29;
/// Pixels over which an edge under the optical blur alone (sigma about 1 px, plus the
/// pixel) rises from 25 % to 75 % of its step.
const SHARP_RISE: f64 = 1.5;
/// Cells in from the side where a profile starts and ends.
const U0: f64 = 0.2;
const U1: f64 = 1.6;

/// Per side of the marker (top, right, bottom, left in the marker's own frame), the median
/// offset in pixels of the border's inner edge from where the quad's grid puts it (positive:
/// the border is thinner than the grid says, as on a side cut by an occluder), the tolerance
/// that side is held to, and the number of cells measured (0: no evidence, offset NaN).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideOffsets {
    /// Median offset per side, pixels (NaN where no cell was measured).
    pub offset_px: [f64; 4],
    /// The tolerance per side, pixels ([`SideCheck`] at that side's cell width).
    pub tolerance_px: [f64; 4],
    /// Cells measured per side.
    pub cells: [usize; 4],
    /// Per corner of the marker (NW, NE, SE, SW in its own frame), the grey level of the
    /// border cell at that corner, as a fraction of the contrast above the median level of
    /// the border's other cells (0: as dark as the border, 1: as light as a light cell),
    /// that median raised where the border is unevenly lit (the corner's two neighbouring
    /// border cells and some cell of the two far sides lighter than it: the smaller of the
    /// darker neighbour's and the lightest far cell's excess). NaN where the cell could not
    /// be sampled (outside the frame).
    pub corner_level: [f64; 4],
    /// The largest level allowed per corner ([`SideCheck::corner_tolerance`], plus what the
    /// blur across a narrow cell and the motion blur bring in from outside the marker).
    pub corner_tolerance: [f64; 4],
    /// Per side, how far inside the quad's side the border's outer edge lies at most, in
    /// pixels, over the centres of the two border cells at each end of that side
    /// (negative: outside at every one; NaN where no cell had a light outside to measure
    /// against).
    pub outer_inset_px: [f64; 4],
    /// The largest inset allowed per side: [`SideCheck::outer_tolerance_px`], plus the
    /// larger blur leak of the side's two corners (the `1 - Phi Phi` term of
    /// [`SideOffsets::corner_tolerance`], taken as pixels), plus
    /// [`SideCheck::outer_sag_per_px2`] times the side's squared length, plus
    /// [`SideCheck::tolerance_motion`] of the motion blur.
    pub outer_tolerance_px: [f64; 4],
    /// The largest step, over the outer-edge profiles of every side, from the lightest
    /// level outside the side to the darkest of the border inside it, as a fraction of the
    /// marker's contrast (NaN where no profile could be sampled, e.g. every side at the
    /// frame's edge).
    pub outside_step: f64,
    /// The smallest `outside_step` allowed ([`SideCheck::min_outside_step`]).
    pub min_outside_step: f64,
}

impl SideOffsets {
    /// Whether no side with evidence has a border thinner than the grid says by more than
    /// its tolerance. Only that direction counts: a cut makes the border thinner, while
    /// motion blur pulls refined corners outwards and makes it read thicker (on 5 px of
    /// motion, inner edges up to 0.8 px outside the grid's; 9 px, 1.3 px). Also that no
    /// corner's border cell reads light, no outer edge lies inside the quad, and some side
    /// shows a light outside ([`SideOffsets::outside_step`]).
    pub fn consistent(&self) -> bool {
        (0..4).all(|s| self.cells[s] == 0 || self.offset_px[s] <= self.tolerance_px[s])
            && self
                .corner_level
                .iter()
                .zip(&self.corner_tolerance)
                .all(|(&c, &t)| c.is_nan() || c <= t)
            && self
                .outer_inset_px
                .iter()
                .zip(&self.outer_tolerance_px)
                .all(|(&d, &t)| d.is_nan() || d <= t)
            // No outside sampled (NaN) is no evidence against.
            && self.outside_step.partial_cmp(&self.min_outside_step) != Some(std::cmp::Ordering::Less)
    }
}

/// Measures the inner border edges of marker `d` (read from `img` with a dictionary of
/// `family`); see the module docs. `None` if the quad's grid cannot be built (the decoder
/// would have rejected such a quad already).
pub fn side_offsets(
    img: &GrayView<'_>,
    d: &Decoded,
    family: MarkerFamily,
    check: &SideCheck,
) -> Option<SideOffsets> {
    let frame = CrossRatioFrame::new(&d.corners).ok()?;
    let wc = f64::from(family.width_cells());
    let hc = f64::from(family.height_cells());
    let (rows, cols) = (family.rows(), family.cols());
    let mut out = SideOffsets {
        offset_px: [f64::NAN; 4],
        tolerance_px: [0.0; 4],
        cells: [0; 4],
        corner_level: [f64::NAN; 4],
        corner_tolerance: [check.corner_tolerance; 4],
        outer_inset_px: [f64::NAN; 4],
        outer_tolerance_px: [check.outer_tolerance_px; 4],
        outside_step: f64::NAN,
        min_outside_step: check.min_outside_step,
    };
    let mut rise = [0.0f64; 4];
    let mut cell = [0.0f64; 4];
    for side in 0..4 {
        let along_cells = if side % 2 == 0 { cols } else { rows };
        let mut offsets = [0.0f64; MAX_CELLS];
        let mut cell_px = [0.0f64; MAX_CELLS];
        let mut rises = [0.0f64; MAX_CELLS];
        let mut n = 0;
        for k in 0..along_cells.min(MAX_CELLS as u32) {
            // The data cell touching the border at position k along this side.
            let (row, col) = match side {
                0 => (0, k),
                1 => (k, cols - 1),
                2 => (rows - 1, k),
                _ => (k, 0),
            };
            if family.bit(d.code, row, col) {
                continue; // black: no inner border edge here
            }
            // Marker coordinates (cells, border included) of a point `u` cells in from
            // this side, `v` cells along it (v measured in the data cell's own position).
            let kf = f64::from(k) + 1.5; // centre of the cell, border cell counted
            let to_ab = |u: f64, v: f64| side_to_ab(side, wc, hc, u, v);
            let Some(prof) = profile::<SAMPLES, true>(img, &frame, &to_ab, U0, U1, kf, 0.25) else {
                continue;
            };
            // Darkest sample of the first half (inside the border), lightest of the second
            // (inside the data cell); the edge is the first crossing of their mean after
            // the darkest sample.
            let half = SAMPLES / 2;
            let (jlo, lo) = darkest(&prof[..half]);
            let hi = prof[half..]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            let step = hi - lo;
            if step.is_nan() || step < check.min_step * d.contrast.max(1.0) {
                continue;
            }
            // First crossing of `lo + t (hi - lo)` after the darkest sample, in cells.
            let cross = |t: f64| {
                let level = lo + t * (hi - lo);
                let j = (jlo..SAMPLES - 1).find(|&j| prof[j] < level && prof[j + 1] >= level)?;
                let f = (level - prof[j]) / (prof[j + 1] - prof[j]);
                Some(U0 + (U1 - U0) * (j as f64 + f) / (SAMPLES - 1) as f64)
            };
            let (Some(u), Some(u25), Some(u75)) = (cross(0.5), cross(0.25), cross(0.75)) else {
                continue;
            };
            // Pixels per cell across the side, here: perpendicular to the border (the
            // direction the blur and the edge's error act in, and the outer edges' check
            // measures), not along the grid's line through the cell, which on a sheared quad
            // (a tag seen obliquely) meets the side at a slant and is longer by 1 / sin of
            // the angle between them.
            let (a0, b0) = to_ab(0.5, kf);
            let (a1, b1) = to_ab(1.5, kf);
            let (ae, be) = to_ab(0.5, kf + 0.5);
            let (Some(p0), Some(p1), Some(pe)) =
                (frame.map(a0, b0), frame.map(a1, b1), frame.map(ae, be))
            else {
                continue;
            };
            let (across, along) = (p1 - p0, pe - p0);
            let px = (across.x * along.y - across.y * along.x).abs() / along.norm();
            if px.is_nan() || px < check.min_cell_px {
                continue;
            }
            // Positive when the edge is nearer the side than the grid says (u < 1).
            offsets[n] = (1.0 - u) * px;
            cell_px[n] = px;
            rises[n] = (u75 - u25) * px;
            n += 1;
        }
        out.cells[side] = n;
        if n > 0 {
            cell[side] = median(&mut cell_px[..n]);
            out.offset_px[side] = median(&mut offsets[..n]);
            rise[side] = median(&mut rises[..n]);
        }
    }
    // The smear: a box blur of width `m` across an edge makes it rise from 25 % to 75 % over
    // `m / 2`, an edge under the optical blur alone over about 1.5 px. The slowest side
    // tells the motion; the corners (hence the grid) of a smeared marker are off by a
    // fraction of it on every side.
    let (length, outer_rise) = outer_edges(img, &frame, wc, hc, d.contrast, check, &mut out);
    let inner_rise = rise.iter().copied().fold(0.0, f64::max);
    // The outer edges are the quad's own sides, whatever grid is read inside: a smear
    // widens them as much as the inner edges, while a grid read across the wrong aspect
    // (a cut quad decoded one corner round) makes the inner profiles rise slowly with no
    // smear at all. The smear is the smaller of the two (`f64::min` keeps the inner figure
    // when no outer edge was measured, NaN).
    let motion = 2.0 * (inner_rise.min(outer_rise) - SHARP_RISE).max(0.0);
    for ((tol, &n), &c) in out.tolerance_px.iter_mut().zip(&out.cells).zip(&cell) {
        if n > 0 {
            *tol = check.tolerance_px + check.tolerance_cells * c + check.tolerance_motion * motion;
        }
    }
    let leak = corner_levels(img, &frame, wc, hc, d.contrast, motion, check, &mut out);
    for (side, tol) in out.outer_tolerance_px.iter_mut().enumerate() {
        *tol = check.outer_tolerance_px
            + leak[side].max(leak[(side + 1) % 4])
            + check.outer_sag_per_px2 * length[side] * length[side]
            + check.tolerance_motion * motion;
    }
    Some(out)
}

/// Fills [`SideOffsets::corner_level`] and the tolerance: the border cell at each corner
/// of the quad's grid, sampled around its centre, against the median of the border's other
/// cells. A cut-off corner gives itself away there: when an occluder's edge crosses the
/// two sides next to a corner, the corner the detector finds (where the sides' fitted lines
/// meet, or a vertex of the cut) lies on or beyond the occluder, and so does the border
/// cell the grid puts at it, which then reads as light as the occluder (about 0.3 to 0.9 of
/// the contrast on 300 rendered corner cuts, against 0.1 or less on the whole corners of
/// the same faces). The tolerance adds the light that the blur brings in from outside the
/// marker at the samples of a whole corner: `1 - Phi(du / s) Phi(dv / s)`, averaged over
/// the samples, with `du`, `dv` their distances in pixels from the two outer sides and
/// `s` the optical blur (1 px) combined with the measured motion blur (a box of width `m`
/// adds `m^2 / 12` to the variance), so narrow cells and smeared markers keep their corners.
#[allow(clippy::too_many_arguments)]
fn corner_levels(
    img: &GrayView<'_>,
    frame: &CrossRatioFrame,
    wc: f64,
    hc: f64,
    contrast: f64,
    motion: f64,
    check: &SideCheck,
    out: &mut SideOffsets,
) -> [f64; 4] {
    let mut leaks = [0.0f64; 4];
    // A point `(x, y)` cells from the marker's NW corner, in the image.
    let point = |x: f64, y: f64| frame.map(-1.0 + 2.0 * x / wc, -1.0 + 2.0 * y / hc);
    // The grey level there (`None` outside the frame).
    let level_at =
        |q: nalgebra::Point2<f64>| inside(img, q.x, q.y).then(|| bilinear(img, q.x, q.y));
    let at = |x: f64, y: f64| point(x, y).and_then(level_at);
    // The border's black: the median of its cells other than the corners.
    let mut border = [0.0f64; 4 * MAX_CELLS];
    let mut n = 0;
    // The lightest of those cells per side (top, right, bottom, left).
    let mut lightest = [f64::NAN; 4];
    let (nx, ny) = (wc as usize, hc as usize);
    for i in 1..nx.saturating_sub(1) {
        for (side, y) in [(0, 0.5), (2, hc - 0.5)] {
            if let (Some(v), true) = (at(i as f64 + 0.5, y), n < border.len()) {
                border[n] = v;
                lightest[side] = lightest[side].max(v);
                n += 1;
            }
        }
    }
    for i in 1..ny.saturating_sub(1) {
        for (side, x) in [(3, 0.5), (1, wc - 0.5)] {
            if let (Some(v), true) = (at(x, i as f64 + 0.5), n < border.len()) {
                border[n] = v;
                lightest[side] = lightest[side].max(v);
                n += 1;
            }
        }
    }
    if n == 0 || contrast.is_nan() || contrast <= 0.0 {
        return leaks;
    }
    let black = median(&mut border[..n]);
    let sigma = (1.0 + motion * motion / 12.0).sqrt();
    // Corners in the marker's own frame (cells) and the directions into the marker.
    let corners = [
        (0.0, 0.0, 1.0, 1.0),
        (wc, 0.0, -1.0, 1.0),
        (wc, hc, -1.0, -1.0),
        (0.0, hc, 1.0, -1.0),
    ];
    for (k, &(cx, cy, sx, sy)) in corners.iter().enumerate() {
        // The corner and its two sides' lines in the image: a sample's distances from
        // them (perpendicular, so a sheared quad's narrow cells count as narrow) are what
        // the blur spans.
        let (Some(c), Some(ex), Some(ey)) = (point(cx, cy), point(wc - cx, cy), point(cx, hc - cy))
        else {
            continue;
        };
        let (Some(ux), Some(uy)) = ((ex - c).try_normalize(1e-9), (ey - c).try_normalize(1e-9))
        else {
            continue;
        };
        // Distance of `q` from the line through `c` along `u`.
        let off = |q: nalgebra::Point2<f64>, u: nalgebra::Vector2<f64>| {
            let w = q - c;
            (w.x * u.y - w.y * u.x).abs()
        };
        // Mean level and mean expected blur leak of the border cell `i` cells along the top
        // or bottom side and `j` along the left or right one from the corner's cell, over
        // the corner samples' pattern.
        let cell = |i: f64, j: f64| {
            let (mut sum, mut leak, mut m) = (0.0, 0.0, 0.0);
            for du in CORNER_SAMPLES {
                for dv in CORNER_SAMPLES {
                    let (x, y) = (cx + (du + i) * sx, cy + (dv + j) * sy);
                    let Some(q) = point(x, y) else {
                        continue;
                    };
                    let Some(v) = level_at(q) else {
                        continue;
                    };
                    sum += v;
                    leak += 1.0 - normal_cdf(off(q, ux) / sigma) * normal_cdf(off(q, uy) / sigma);
                    m += 1.0;
                }
            }
            (m > 0.0).then(|| ((sum / m - black) / contrast, leak / m))
        };
        if let Some((level, leak)) = cell(0.0, 0.0) {
            // The border's black near the corner. A whole border need not be evenly dark:
            // glare on a glossy print or shading lights parts of it (issue #31: the NASA
            // photo's third tag, border cells from 7 to 68 grey levels on a contrast of 80,
            // its NW corner cell 0.42 of the contrast above the median). Where that lights
            // the corner cell, its two neighbours along the sides are lit too, and the
            // border shows light cells away from that corner as well. An occluder over the
            // corner lights the corner cell but leaves at least one neighbour dark unless it
            // hides 1.4 cells or more of the corner, and never reaches the two far sides (a
            // corner cut stops short of the middle of its sides). So the corner's level is
            // taken above the median raised by the smaller of the darker neighbour's excess
            // (less the blur leak expected there) and the lightest far-side cell's excess:
            // both must show an uneven border.
            let near = match (cell(1.0, 0.0), cell(0.0, 1.0)) {
                (Some((a, la)), Some((b, lb))) => (a - la).min(b - lb),
                _ => 0.0,
            };
            let far = (lightest[(k + 1) % 4].max(lightest[(k + 2) % 4]) - black) / contrast;
            // (No far cell sampled: no evidence of an uneven border.)
            let local = if far.is_nan() {
                0.0
            } else {
                near.min(far).max(0.0)
            };
            out.corner_level[k] = level - local;
            leaks[k] = leak;
            out.corner_tolerance[k] = check.corner_tolerance + leaks[k];
        }
    }
    leaks
}

/// Fills [`SideOffsets::outer_inset_px`] and returns the sides' lengths in pixels and the
/// slowest side's median rise of the outer edge (25 % to 75 %, pixels; NaN without one). Per
/// side, at the centre of the two border cells at each end (the corner cell and the next),
/// the grey profile across the side from 0.6 cell outside to 0.6 cell inside (three
/// parallel lines, averaged) gives the outer edge: the last crossing of the mean of its light outside and its dark
/// border before the border's darkest sample. A profile whose outside is not lighter than
/// the border by [`SideCheck::min_step`] of the contrast (the marker touches something
/// dark) gives no evidence.
///
/// This is what a cut-off corner leaves when the occluder's edge runs at a shallow angle
/// to a side: the fitted side follows the occluder part of the way, the corner slides
/// inwards along the other side and the corner cell stays dark, but near that corner the
/// occluder's edge, which is the outline there, lies well inside the quad (1-3 px on
/// rendered cuts, against 0.14 px at most on whole faces). Only that direction counts:
/// where the outline lies outside the quad, a real marker may touch something as dark as
/// its border.
fn outer_edges(
    img: &GrayView<'_>,
    frame: &CrossRatioFrame,
    wc: f64,
    hc: f64,
    contrast: f64,
    check: &SideCheck,
    out: &mut SideOffsets,
) -> ([f64; 4], f64) {
    let mut length = [0.0f64; 4];
    // The slowest side's median rise (NaN until a side has one).
    let mut slowest = f64::NAN;
    const N: usize = 13;
    const UO: f64 = -0.6;
    const UI: f64 = 0.6;
    for (side, side_length) in length.iter_mut().enumerate() {
        let along = if side % 2 == 0 { wc } else { hc };
        let to_ab = |u: f64, v: f64| side_to_ab(side, wc, hc, u, v);
        let mut offs = [0.0f64; 4];
        let mut rises = [0.0f64; 4];
        let (mut n, mut m) = (0, 0);
        let (end0, end1) = {
            let (a0, b0) = to_ab(0.0, 0.0);
            let (a1, b1) = to_ab(0.0, along);
            (frame.map(a0, b0), frame.map(a1, b1))
        };
        if let (Some(p), Some(q)) = (end0, end1) {
            *side_length = (q - p).norm();
        }
        // The side's unit normal, pointing into the quad (the grid's direction across the
        // side, at its middle): an inset is a distance along it from the side's line.
        let normal = {
            let (a0, b0) = to_ab(0.0, 0.5 * along);
            let (a1, b1) = to_ab(1.0, 0.5 * along);
            let (Some(e0), Some(e1), Some(p0), Some(p1)) =
                (end0, end1, frame.map(a0, b0), frame.map(a1, b1))
            else {
                continue;
            };
            let Some(dir) = (e1 - e0).try_normalize(1e-9) else {
                continue;
            };
            let normal = nalgebra::Vector2::new(-dir.y, dir.x);
            if normal.dot(&(p1 - p0)) < 0.0 {
                -normal
            } else {
                normal
            }
        };
        // The two border cells at each end: a cut corner's inset is largest there (the
        // middle of a side cut along its length is the inner edge's business).
        let cells = along as usize;
        for k in [0, 1, cells.saturating_sub(2), cells.saturating_sub(1)] {
            let v = k as f64 + 0.5;
            let Some(prof) = profile::<N, true>(img, frame, &to_ab, UO, UI, v, 0.15) else {
                continue;
            };
            // Lightest sample of the outer half, darkest of the inner (the border).
            let half = N / 2;
            let hi = prof[..half]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            let (jlo, lo) = darkest(&prof[half..]);
            let jlo = jlo + half;
            let step = hi - lo;
            out.outside_step = out.outside_step.max(step / contrast.max(1.0));
            if step.is_nan() || step < check.min_step * contrast.max(1.0) {
                continue;
            }
            // Last light-to-dark crossing of `hi - t (hi - lo)` before the darkest sample,
            // in the image.
            let cross = |t: f64| {
                let level = hi - t * step;
                let j = (0..jlo)
                    .rev()
                    .find(|&j| prof[j] >= level && prof[j + 1] < level)?;
                let f = (prof[j] - level) / (prof[j] - prof[j + 1]);
                let (a, b) = to_ab(UO + (UI - UO) * (j as f64 + f) / (N - 1) as f64, v);
                frame.map(a, b)
            };
            let (Some(q), Some(e0)) = (cross(0.5), end0) else {
                continue;
            };
            // Signed distance from the side's line, positive into the quad.
            offs[n] = (q - e0).dot(&normal);
            if let (Some(q25), Some(q75)) = (cross(0.25), cross(0.75)) {
                rises[m] = (q75 - q25).dot(&normal).abs();
                m += 1;
            }
            n += 1;
        }
        if n > 0 {
            out.outer_inset_px[side] = offs[..n].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        }
        if m > 0 {
            slowest = slowest.max(median(&mut rises[..m]));
        }
    }
    (length, slowest)
}

/// Marker coordinates (the quad's `[-1, 1]^2`) of a point `u` cells in from side `side`
/// (0 top, 1 right, 2 bottom, 3 left, in the marker's own frame) and `v` cells along it,
/// for a marker `wc` x `hc` cells, border included.
fn side_to_ab(side: usize, wc: f64, hc: f64, u: f64, v: f64) -> (f64, f64) {
    let (x, y) = match side {
        0 => (v, u),
        1 => (wc - u, v),
        2 => (v, hc - u),
        _ => (u, v),
    };
    (-1.0 + 2.0 * x / wc, -1.0 + 2.0 * y / hc)
}

/// `N` grey levels across a side, from `u0` to `u1` cells in from it at `v` cells along it
/// (coordinates through `to_ab`), each the mean of bilinear samples on three parallel
/// lines `spread` cells apart. `None` if a sample falls outside the frame. `to_ab` must be
/// affine (as [`side_to_ab`] is): each line is then a segment of the frame's homography,
/// mapped end to end ([`CrossRatioFrame::segment`]).
///
/// With `FAST` (the detector's), lines wholly inside the frame are read without the
/// per-sample check and clamping; without it every sample is checked (the tests'
/// reference).
#[allow(clippy::too_many_arguments)]
fn profile<const N: usize, const FAST: bool>(
    img: &GrayView<'_>,
    frame: &CrossRatioFrame,
    to_ab: &impl Fn(f64, f64) -> (f64, f64),
    u0: f64,
    u1: f64,
    v: f64,
    spread: f64,
) -> Option<[f64; N]> {
    let mut prof = [0.0f64; N];
    // The three lines, each a segment of the frame from u0 to u1.
    let line = |dv: f64| frame.segment(to_ab(u0, v + dv), to_ab(u1, v + dv));
    let lines = [line(-spread)?, line(0.0)?, line(spread)?];
    // Lines whose ends lie inside the frame by a margin lie wholly inside it (a homography
    // maps a segment that does not reach the horizon to a segment): their samples are read
    // without the per-sample check and clamping (the same values).
    let m = 1e-6;
    let within = |p: Option<nalgebra::Point2<f64>>| {
        p.is_some_and(|q| img.within(q.x - m, q.y - m) && img.within(q.x + m, q.y + m))
    };
    if FAST && lines.iter().all(|l| within(l.at(0.0)) && within(l.at(1.0))) {
        for (j, p) in prof.iter_mut().enumerate() {
            let f = j as f64 / (N - 1) as f64;
            let mut sum = 0.0;
            for l in &lines {
                let q = l.at(f)?;
                sum += bilinear_inside(img, q.x, q.y);
            }
            *p = sum / 3.0;
        }
        return Some(prof);
    }
    for (j, p) in prof.iter_mut().enumerate() {
        let f = j as f64 / (N - 1) as f64;
        let mut sum = 0.0;
        for l in &lines {
            let q = l.at(f)?;
            if !inside(img, q.x, q.y) {
                return None;
            }
            sum += bilinear(img, q.x, q.y);
        }
        *p = sum / 3.0;
    }
    Some(prof)
}

/// Index and level of the darkest sample (the first of equals; `(0, inf)` if empty).
fn darkest(prof: &[f64]) -> (usize, f64) {
    prof.iter().copied().enumerate().fold(
        (0, f64::INFINITY),
        |a, (j, v)| if v < a.1 { (j, v) } else { a },
    )
}

/// Where a corner's border cell is sampled, in cells from each of the corner's two sides:
/// around the cell's centre, not nearer the outer sides than 0.35 cell.
const CORNER_SAMPLES: [f64; 3] = [0.35, 0.5, 0.65];

/// The standard normal distribution function (Abramowitz and Stegun 26.2.17, error under
/// 7.5e-8); also the reference of [`crate::pattern`]'s interpolated table.
pub(crate) fn normal_cdf(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.231_641_9 * z);
    let poly = t
        * (0.319_381_530
            + t * (-0.356_563_782
                + t * (1.781_477_937 + t * (-1.821_255_978 + t * 1.330_274_429))));
    let tail = (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt() * poly;
    if x >= 0.0 { 1.0 - tail } else { tail }
}

/// Whether `(x, y)` is inside the frame (bilinear reads there need no clamping).
fn inside(img: &GrayView<'_>, x: f64, y: f64) -> bool {
    x >= 0.0 && y >= 0.0 && x <= img.max_x() && y <= img.max_y()
}

/// Median of a non-empty slice (reordered).
fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Point2;

    #[test]
    fn normal_cdf_matches_known_values() {
        for (x, p) in [
            (0.0, 0.5),
            (1.0, 0.841_344_746),
            (1.959_963_985, 0.975),
            (-2.0, 0.022_750_132),
            (4.0, 0.999_968_329),
        ] {
            assert!(
                (normal_cdf(x) - p).abs() < 1e-7,
                "Phi({x}) = {}",
                normal_cdf(x)
            );
            assert!((normal_cdf(-x) - (1.0 - p)).abs() < 1e-7);
        }
        assert!(normal_cdf(f64::NAN).is_nan());
        assert_eq!(normal_cdf(f64::INFINITY), 1.0);
        assert_eq!(normal_cdf(f64::NEG_INFINITY), 0.0);
    }

    proptest::proptest! {
        /// Profiles read on the fast path (lines wholly inside the frame) are bit for bit
        /// those read sample by sample, and a profile leaving the frame is `None` on both.
        #[test]
        fn fast_profiles_match_the_checked_ones(
            seed in proptest::prelude::any::<u64>(),
            x0 in -10.0f64..40.0,
            y0 in -10.0f64..40.0,
            size in 4.0f64..40.0,
            skew in -0.2f64..0.2,
            side in 0usize..4,
            v in 0.0f64..8.0,
        ) {
            let (w, h) = (48usize, 40usize);
            let px = crate::test_bytes(seed, w * h, |_, state| {
                state as u8
            });
            let img = GrayView::new(&px, w, h).unwrap();
            let corners = [
                Point2::new(x0, y0),
                Point2::new(x0 + size, y0 + skew * size),
                Point2::new(x0 + size * (1.0 + skew), y0 + size),
                Point2::new(x0 - skew * size, y0 + size * (1.0 - skew)),
            ];
            let Ok(frame) = CrossRatioFrame::new(&corners) else {
                return Ok(());
            };
            let to_ab = |u: f64, v: f64| side_to_ab(side, 8.0, 9.0, u, v);
            let fast = profile::<SAMPLES, true>(&img, &frame, &to_ab, U0, U1, v, 0.25);
            let checked = profile::<SAMPLES, false>(&img, &frame, &to_ab, U0, U1, v, 0.25);
            proptest::prop_assert_eq!(fast.map(|p| p.map(f64::to_bits)), checked.map(|p| p.map(f64::to_bits)));
        }
    }

    #[test]
    fn darkest_takes_the_first_of_equals() {
        assert_eq!(darkest(&[3.0, 1.0, 2.0, 1.0]), (1, 1.0));
        assert_eq!(darkest(&[]), (0, f64::INFINITY));
    }

    #[test]
    fn side_coordinates_run_along_each_side_from_its_first_corner() {
        // A 7 x 6 cell marker: `v` runs from the west end of the top and bottom sides and
        // from the north end of the right and left ones.
        assert_eq!(side_to_ab(0, 7.0, 6.0, 0.0, 0.0), (-1.0, -1.0));
        assert_eq!(side_to_ab(1, 7.0, 6.0, 0.0, 0.0), (1.0, -1.0));
        assert_eq!(side_to_ab(2, 7.0, 6.0, 0.0, 7.0), (1.0, 1.0));
        assert_eq!(side_to_ab(3, 7.0, 6.0, 0.0, 6.0), (-1.0, 1.0));
        // One cell in from the top, at the middle: inside.
        let (a, b) = side_to_ab(0, 7.0, 6.0, 1.0, 3.5);
        assert!((a - 0.0).abs() < 1e-12 && (b - (-1.0 + 2.0 / 6.0)).abs() < 1e-12);
    }
}
