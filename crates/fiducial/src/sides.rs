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
//! from the grid's prediction, in pixels, is taken per side as the median over its cells.
//! A side whose median offset (border thinner than the grid says) is larger than [`SideCheck::tolerance_px`] (plus
//! [`SideCheck::tolerance_cells`] of a cell, plus [`SideCheck::tolerance_motion`] of the
//! motion blur across the side) is not the marker's side, and the marker is dropped. A side with no light data cell next to it, or whose profiles are too flat (a
//! heavily blurred marker), gives no evidence and passes. No allocation: every buffer is a
//! fixed array.

use crate::cross_ratio::CrossRatioFrame;
use crate::decode::Decoded;
use crate::family::MarkerFamily;
use crate::image::GrayView;
use crate::refine::bilinear;

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
    /// from how slowly the border's inner edges rise (25 % to 75 % of the step, slowest
    /// side) beyond an edge under the optical blur alone: the refined corners of a smeared
    /// marker are off by a fraction of the smear.
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
}

impl SideOffsets {
    /// Whether no side with evidence has a border thinner than the grid says by more than
    /// its tolerance. Only that direction counts: a cut makes the border thinner, while
    /// motion blur pulls refined corners outwards and makes it read thicker (on 5 px of
    /// motion, inner edges up to 0.8 px outside the grid's; 9 px, 1.3 px).
    pub fn consistent(&self) -> bool {
        (0..4).all(|s| self.cells[s] == 0 || self.offset_px[s] <= self.tolerance_px[s])
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
            let to_ab = |u: f64, v: f64| -> (f64, f64) {
                let (x, y) = match side {
                    0 => (v, u),
                    1 => (wc - u, v),
                    2 => (v, hc - u),
                    _ => (u, v),
                };
                (-1.0 + 2.0 * x / wc, -1.0 + 2.0 * y / hc)
            };
            let mut prof = [0.0f64; SAMPLES];
            let mut ok = true;
            for (j, p) in prof.iter_mut().enumerate() {
                let u = U0 + (U1 - U0) * j as f64 / (SAMPLES - 1) as f64;
                let mut sum = 0.0;
                for dv in [-0.25, 0.0, 0.25] {
                    let (a, b) = to_ab(u, kf + dv);
                    match frame.map(a, b) {
                        Some(q) if inside(img, q.x, q.y) => sum += bilinear(img, q.x, q.y),
                        _ => ok = false,
                    }
                }
                *p = sum / 3.0;
            }
            if !ok {
                continue;
            }
            // Darkest sample of the first half (inside the border), lightest of the second
            // (inside the data cell); the edge is the first crossing of their mean after
            // the darkest sample.
            let half = SAMPLES / 2;
            let (jlo, lo) =
                prof[..half]
                    .iter()
                    .copied()
                    .enumerate()
                    .fold(
                        (0, f64::INFINITY),
                        |a, (j, v)| if v < a.1 { (j, v) } else { a },
                    );
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
            // Pixels per cell across the side, here.
            let (a0, b0) = to_ab(0.5, kf);
            let (a1, b1) = to_ab(1.5, kf);
            let (Some(p0), Some(p1)) = (frame.map(a0, b0), frame.map(a1, b1)) else {
                continue;
            };
            let px = (p1 - p0).norm();
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
    let motion = 2.0 * (rise.iter().copied().fold(0.0, f64::max) - SHARP_RISE).max(0.0);
    for ((tol, &n), &c) in out.tolerance_px.iter_mut().zip(&out.cells).zip(&cell) {
        if n > 0 {
            *tol = check.tolerance_px + check.tolerance_cells * c + check.tolerance_motion * motion;
        }
    }
    Some(out)
}

/// Whether `(x, y)` is inside the frame (bilinear reads there need no clamping).
fn inside(img: &GrayView<'_>, x: f64, y: f64) -> bool {
    x >= 0.0 && y >= 0.0 && x <= (img.width() - 1) as f64 && y <= (img.height() - 1) as f64
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
