//! Reading a quad whose cells are smeared by motion blur (issue #16).
//!
//! A camera moving while the shutter is open smears the image along one direction: every
//! pixel is the mean of the sharp image along a segment `u` (the motion during the
//! exposure, pixels). Edges along the motion stay sharp, edges across it become ramps of
//! the blur length, and on a small marker a dark cell bleeds into its light neighbours until
//! the cell centres no longer read right.
//!
//! When the plain reading of a quad passed the contrast check and its border read dark
//! (or was rejected only for light border cells) but its code is not a dictionary entry,
//! the detector calls [`decode_blurred`]: the motion is estimated from the quad's own
//! edges (the spread of the grey-level step across each side is the optical blur plus the
//! motion's component along the side's normal). A motion under 1.5 cells is left to the
//! plain reading, and so is a quad whose step across the sides most across the motion is
//! not a ramp but sharp steps a cell apart (a sharp quad's border and a cell edge inside
//! it, which also spread the step), and one whose outline is not smeared outwards on any
//! side by more than a sharp edge and a fifth of the motion ([`MIN_BLUR_SMEAR`]): the
//! motion read from its step widths then comes from edges inside it. For each candidate
//! motion (the estimate's two sign choices, each also 25 % shorter and longer; the shorter
//! and longer only for the sign that fits better at the estimate) the grid's cell levels
//! (the marker, its quiet zone and the cells around) are solved by least squares from samples inside every cell, each
//! modelled as the mean of the cells its blur segment crosses (weighted by the length of
//! the segment inside each cell; the normal equations keep a narrow envelope, which the
//! Cholesky factorisation exploits). The
//! candidate that explains the samples best gives the levels, which are read as
//! [`crate::decode::read_cells`] reads sampled levels. Hard bit correction is off (as in
//! the default detector); the soft decision of [`DecodeParams`] applies. When no reading
//! matches, the entry whose differing cells have the least summed margin is read if that
//! sum is small, within the correction radius, and clearly below every other entry's
//! ([`least_cost_match`]): in a deconvolved reading the cells read wrong are weak ones,
//! but not always the two weakest.

use nalgebra::{Point2, Vector2};

use crate::cross_ratio::CrossRatioFrame;
use crate::decode::{
    CellReading, DecodeParams, Decoded, WhiteReference, decoded_from_match, match_reading,
    reading_from_levels,
};
use crate::dictionary::{Dictionary, Match};
use crate::family::MarkerFamily;
use crate::image::{Corners, GrayView};

/// Optical blur assumed under the motion (variance of the step's derivative, px^2): the
/// renderer's blur sigma 1 and the pixel's own width.
const OPTICAL_VARIANCE: f64 = 1.1;

/// Shortest motion worth modelling, pixels.
const MIN_MOTION: f64 = 1.5;

/// Shortest motion worth modelling, in cells of the grid (see [`decode_blurred`]).
const MIN_MOTION_CELLS: f64 = 1.5;

/// Smallest cell pitch (pixels, along the quad's shorter sides) worth the blurred reading.
/// Under the optical blur of the model ([`OPTICAL_VARIANCE`], sigma about 1 px) a pattern of
/// cells `p` px wide keeps `exp(-2 pi^2 sigma^2 / (2 p)^2)` of its contrast before any motion:
/// 29 % at 2 px, 11 % at 1.5 px, under 1 % at 1 px, so smaller cells cannot be solved for.
/// On the motion-blur rows (`cargo xtask detector-accuracy --motion-blur`, seeds
/// 81,000-81,019 and 83,000-83,039, markers of 20-70 px) the smallest pitch read was
/// 1.94 px and the smallest that reached the solves 1.53 px; on `board.jpg` two of the three
/// quads that reached them (none a marker) had cells of 1.05 and 1.27 px.
const MIN_BLUR_PITCH: f64 = 1.5;

/// Bilinear grey level at `p`, `None` outside the image ([`crate::decode`]'s sampler).
fn bilinear(image: &GrayView<'_>, p: Point2<f64>) -> Option<f64> {
    crate::decode::bilinear(image, p.x, p.y)
}

/// The step across side `i` (corners `i` to `i + 1`): its width beyond the optical blur
/// (the motion's component along the side's normal, pixels) and how peaked the step is
/// for that width (`None` when no step is measured).
///
/// The peakedness is the mean over the stations of the largest half-pixel change of the
/// profile as a share of the profile's total change, times the width: a ramp of width `W`
/// changes by about `0.5 / W` of its total in each half pixel, so a motion-blurred edge
/// reads about 0.5 (0.39-0.73 on the motion-blur scenes, seeds 90,000-90,039, every length).
/// The width is read from the spread of the changes, so two sharp steps a cell apart (the
/// border's outer edge and a cell edge inside a sharp quad) also read as a wide step, but
/// each of them is a spike: they read up to 2 ([`MAX_RAMP_PEAK`]).
fn step_width(image: &GrayView<'_>, corners: &Corners, i: usize) -> Option<(f64, f64)> {
    let (p, q) = (corners[i], corners[(i + 1) % 4]);
    let along = q - p;
    let len = along.norm();
    if len.is_nan() || len <= 4.0 {
        return None;
    }
    let n = Vector2::new(along.y, -along.x) / len;
    let reach = (0.6 * len / 4.0).clamp(3.0, 10.0);
    let (mut sw, mut s1, mut s2) = (0.0, 0.0, 0.0);
    let (mut peaks, mut stations) = (0.0, 0u32);
    for k in 1..8 {
        let base = p + along * (f64::from(k) / 8.0);
        let mut prev: Option<f64> = None;
        let mut t = -reach;
        let (mut total, mut peak) = (0.0f64, 0.0f64);
        while t <= reach {
            let v = bilinear(image, base + n * t);
            if let (Some(a), Some(b)) = (prev, v) {
                // Either polarity: the side's outward direction is not known here.
                let d = (b - a).abs();
                let tm = t - 0.25;
                sw += d;
                s1 += d * tm;
                s2 += d * tm * tm;
                total += d;
                peak = peak.max(d);
            }
            prev = v;
            t += 0.5;
        }
        if total > 0.0 {
            peaks += peak / total;
            stations += 1;
        }
    }
    if sw.is_nan() || sw <= 0.0 || stations == 0 {
        return None;
    }
    let mean = s1 / sw;
    let var = s2 / sw - mean * mean;
    let width = (12.0 * (var - OPTICAL_VARIANCE).max(0.0)).sqrt();
    Some((width, width * peaks / f64::from(stations)))
}

/// Most peakedness ([`step_width`]) of the two opposite sides most across an estimated
/// motion for the quad to be read as motion-blurred: their step must be a ramp, not sharp
/// steps a cell apart. On the motion-blur scenes (seeds 90,000-90,039, 3-13 px) no quad
/// read with the motion model exceeded 0.73, read or not at most 1.07; on sharp clutter
/// frames (seeds 43-62) a third of the quads that reached the model read more than 1.
const MAX_RAMP_PEAK: f64 = 1.0;

/// How far outside side `i` of `corners` the smear of the marker reaches: the median over
/// stations along the side of the distance from the side to where the darkness of the
/// profile, outwards, has fallen to a tenth of its value on the side (pixels; `None` when
/// the side is too short or shows no step).
///
/// A box blur of length `r` across a side spreads the border's darkness `0.4 r` to `0.5 r`
/// outside it whatever lies inside (the box there covers only the border and the white
/// margin), while a sharp edge under an optical blur of sigma 1 falls off within about 1.5
/// px. Unlike [`step_width`], which reads the profile across the side and so also sees the
/// edges of whatever lies inside a quad, this looks only outwards, into the marker's quiet
/// zone.
fn outer_reach(image: &GrayView<'_>, corners: &Corners, i: usize, reach: f64) -> Option<f64> {
    let centre = corners.iter().fold(Vector2::zeros(), |a, p| a + p.coords) / 4.0;
    let (p, q) = (corners[i], corners[(i + 1) % 4]);
    let along = q - p;
    let len = along.norm();
    if len.is_nan() || len <= 6.0 {
        return None;
    }
    let t = along / len;
    let mut n = Vector2::new(t.y, -t.x);
    if n.dot(&(p.coords - centre)) < 0.0 {
        n = -n;
    }
    let steps = ((reach / 0.5) as usize).clamp(4, 40);
    let mut found = [0.0f64; 7];
    let mut m = 0;
    for k in 1..8 {
        let base = p + along * (f64::from(k) / 8.0);
        let at = |j: usize| bilinear(image, base + n * (0.5 * j as f64));
        let (Some(on), Some(white)) = (at(0), at(steps)) else {
            continue;
        };
        let dark = white - on;
        if dark.is_nan() || dark < 10.0 {
            continue;
        }
        if let Some(j) = (1..=steps).find(|&j| at(j).is_some_and(|v| white - v <= 0.1 * dark)) {
            found[m] = 0.5 * j as f64;
            m += 1;
        }
    }
    if m < 3 {
        return None;
    }
    let v = &mut found[..m];
    v.sort_unstable_by(f64::total_cmp);
    Some(v[m / 2])
}

/// Most candidate motions: two sign choices at three scales. (A search over eight further
/// directions at two lengths, tried before, gained one marker in 80 at 9 px and cost
/// nearly four times as much on every quad that is not a marker.)
const MAX_MOTIONS: usize = 2 * 3;

/// Candidate motions of `corners` into `out`: from the step widths across two adjacent
/// sides (two sign choices), each also 25 % shorter and longer, in that order (shorter,
/// estimate, longer, for one sign, then the other). Returns the count and the longer
/// estimate's length (pixels); none when the step most across the motion is not a ramp.
fn motions(
    image: &GrayView<'_>,
    corners: &Corners,
    out: &mut [Vector2<f64>; MAX_MOTIONS],
) -> (usize, f64) {
    let steps: [Option<(f64, f64)>; 4] = core::array::from_fn(|i| step_width(image, corners, i));
    // Width and peakedness of a pair of opposite sides (the same normal).
    let pair = |a: usize, b: usize| match (steps[a], steps[b]) {
        (Some(x), Some(y)) => Some((0.5 * (x.0 + y.0), x.1.min(y.1))),
        (Some(x), None) | (None, Some(x)) => Some(x),
        _ => None,
    };
    let (Some((b0, peak0)), Some((b1, peak1))) = (pair(0, 2), pair(1, 3)) else {
        return (0, 0.0);
    };
    // The pair most across the motion must show a ramp (see [`MAX_RAMP_PEAK`]).
    if (if b0 >= b1 { peak0 } else { peak1 }) > MAX_RAMP_PEAK {
        return (0, 0.0);
    }
    let normal = |i: usize| {
        let d = corners[(i + 1) % 4] - corners[i];
        Vector2::new(d.y, -d.x) / d.norm()
    };
    let m = nalgebra::Matrix2::from_rows(&[normal(0).transpose(), normal(1).transpose()]);
    let Some(inv) = m.try_inverse() else {
        return (0, 0.0);
    };
    let mut n = 0;
    let mut length = 0.0f64;
    for sign in [1.0, -1.0] {
        let u = inv * Vector2::new(b0, sign * b1);
        if !(u.norm() >= MIN_MOTION && u.norm().is_finite()) {
            continue;
        }
        length = length.max(u.norm());
        for scale in [0.75, 1.0, 1.25] {
            out[n] = u * scale;
            n += 1;
        }
    }
    (n, length)
}

/// Scratch space of the blurred reading, owned by the detector so that a steady stream of
/// frames reads blurred markers without touching the heap: buffers grow to the largest
/// system solved and are reused.
#[derive(Debug, Clone, Default)]
pub(crate) struct BlurScratch {
    /// The samples of the current grid, independent of the motion: marker-frame position
    /// `(a, b)`, grey level, and the inverse Jacobian of the frame there (row major).
    samples: Vec<[f64; 7]>,
    /// Lower triangle of the normal matrix (`n x n`) within its envelope, row by row
    /// (row `i` holds columns `first[i] ..= i` from `start[i]` on), factored in place.
    ata: Vec<f64>,
    /// Per row of `ata`: its first non-zero column (the envelope the factor keeps).
    first: Vec<usize>,
    /// Per row of `ata`: where its first stored column lies in `ata`.
    start: Vec<usize>,
    /// Per column `j` of `ata`: the last row whose envelope reaches it (`first[i] <= j`).
    last: Vec<usize>,
    /// Right-hand side, then the solution.
    atb: Vec<f64>,
    /// Per sample row: its first weight in `weights`, its weight count and its grey level.
    rows: Vec<(u32, u32, f64)>,
    /// Cell index and weight of every row's blur segment.
    weights: Vec<(u32, f64)>,
    /// Levels of the best candidate so far (and their `k`, misfit).
    best: Vec<f64>,
    /// The readings of the current quad that matched no entry: dictionary, corner shift,
    /// reading (for [`least_cost_match`]).
    unmatched: Vec<(usize, u8, CellReading)>,
    /// Quads whose systems were solved since the count was last reset (diagnostics:
    /// [`crate::DetectStats::blurred`]).
    pub(crate) solved_quads: usize,
}

/// `sum(a[i] * b[i])` in four independent lanes (the factorisation's inner loop).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The storage of an envelope matrix for [`cholesky_solve`], from `first` (per row `i`,
/// its first non-zero column, at most `i`): where each row starts in the storage (`start`;
/// row `i` holds columns `first[i] ..= i`, rows one after the other) and, per column `j`,
/// the last row whose envelope reaches it (`last`, at least `j`). Returns the entries
/// stored.
fn envelope(first: &[usize], start: &mut Vec<usize>, last: &mut Vec<usize>) -> usize {
    start.clear();
    last.clear();
    last.extend(0..first.len());
    let mut at = 0;
    for (i, &f) in first.iter().enumerate() {
        start.push(at);
        let f = f.min(i);
        at += i + 1 - f;
        last[f] = last[f].max(i);
    }
    // A row reaching column f reaches every column after it up to its diagonal.
    for j in 1..last.len() {
        last[j] = last[j].max(last[j - 1]);
    }
    at
}

/// Solves `a x = b` in place for a symmetric positive definite `n x n` matrix whose row `i`
/// has no non-zero left of column `first[i]`, given as the lower triangle of that envelope
/// stored as [`envelope`] lays it out (row `i`'s columns `first[i] ..= i` from
/// `a[start[i]]` on; `last[j]` the last row reaching column `j`): the factor keeps the
/// envelope, so the work and the memory are the envelope's, not `n^3` and `n^2`. Cholesky
/// factor in place, then `b` becomes `x`. `false` if the matrix is not positive definite.
fn cholesky_solve(
    a: &mut [f64],
    [first, start, last]: [&[usize]; 3],
    b: &mut [f64],
    n: usize,
) -> bool {
    if first.len() < n || start.len() < n || last.len() < n || b.len() < n {
        return false;
    }
    // Entry (i, j), first[i] <= j <= i.
    let at = |i: usize, j: usize| start[i] + j - first[i];
    for j in 0..n {
        let fj = first[j];
        let (r0, rj) = (at(j, fj), at(j, j));
        let d = a[rj] - dot(&a[r0..rj], &a[r0..rj]);
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        a[rj] = d;
        // Rows past last[j] do not reach column j.
        let end = last[j].min(n - 1);
        for (i, &fi) in first.iter().enumerate().take(end + 1).skip(j + 1) {
            if fi > j {
                continue;
            }
            let f = fi.max(fj);
            // Row i lies after row j.
            let (top, bottom) = a.split_at_mut(start[i]);
            let (bf, bj) = (f - fi, j - fi);
            let v = bottom[bj] - dot(&bottom[bf..bj], &top[at(j, f)..rj]);
            bottom[bj] = v / d;
        }
    }
    // L y = b, then L^T x = y.
    for i in 0..n {
        let f = first[i];
        b[i] = (b[i] - dot(&a[at(i, f)..at(i, i)], &b[f..i])) / a[at(i, i)];
    }
    for i in (0..n).rev() {
        let bi = b[i] / a[at(i, i)];
        b[i] = bi;
        // Column i of L lies in rows whose envelope reaches i.
        for k in (first[i]..i).rev() {
            b[k] -= a[at(i, k)] * bi;
        }
    }
    b.iter().all(|v| v.is_finite())
}

/// Samples the grid of `family` under `corners` (taken as NW, NE, SE, SW) into
/// `scratch.samples`: nine points in every cell of the grid and its quiet ring, with what
/// [`solve_levels`] needs for any motion. `false` when the frame cannot be mapped.
fn gather_samples(
    image: &GrayView<'_>,
    frame: &CrossRatioFrame,
    family: MarkerFamily,
    scratch: &mut BlurScratch,
) -> bool {
    let (wc, hc) = (family.width_cells() as i32, family.height_cells() as i32);
    let offs = [-1.0 / 3.0, 0.0, 1.0 / 3.0];
    let (pa, pb) = (2.0 / f64::from(wc), 2.0 / f64::from(hc));
    scratch.samples.clear();
    for cy in -1..=hc {
        for cx in -1..=wc {
            for oy in offs {
                for ox in offs {
                    let a = -1.0 + (f64::from(cx) + 0.5 + ox) * pa;
                    let b = -1.0 + (f64::from(cy) + 0.5 + oy) * pb;
                    let Some(p) = frame.map(a, b) else {
                        return false;
                    };
                    let Some(obs) = bilinear(image, p) else {
                        continue;
                    };
                    let e = 1e-3;
                    let (Some(pa_), Some(pb_)) = (frame.map(a + e, b), frame.map(a, b + e)) else {
                        return false;
                    };
                    let j = nalgebra::Matrix2::from_columns(&[(pa_ - p) / e, (pb_ - p) / e]);
                    let Some(inv) = j.try_inverse() else {
                        return false;
                    };
                    scratch.samples.push([
                        a,
                        b,
                        obs,
                        inv[(0, 0)],
                        inv[(0, 1)],
                        inv[(1, 0)],
                        inv[(1, 1)],
                    ]);
                }
            }
        }
    }
    true
}

/// Solves the cell levels of the grid of `family` sampled in `scratch.samples` for the
/// motion `u` into `scratch.atb` (levels of cells `-k..w + k` by `-k..h + k`, row major),
/// and returns the mean squared misfit of the samples; `None` when the system cannot be
/// built.
fn solve_levels(
    family: MarkerFamily,
    u: Vector2<f64>,
    k: i32,
    scratch: &mut BlurScratch,
) -> Option<f64> {
    let (wc, hc) = (family.width_cells() as i32, family.height_cells() as i32);
    let (gw, gh) = (wc + 2 * k, hc + 2 * k);
    let n = (gw * gh) as usize;
    let (pa, pb) = (2.0 / f64::from(wc), 2.0 / f64::from(hc));
    // Cells are numbered along the motion's main axis in the marker frame (row major for a
    // motion mostly along a, column major otherwise), so that a blur segment's cells stay
    // close in index and the normal matrix keeps a narrow envelope.
    let mid = scratch.samples.len() / 2;
    let column_major = scratch.samples.get(mid).is_some_and(|s| {
        let (da, db) = (s[3] * u.x + s[4] * u.y, s[5] * u.x + s[6] * u.y);
        (db / pb).abs() > (da / pa).abs()
    });
    let index = |ix: i32, iy: i32| {
        if column_major {
            (ix * gh + iy) as u32
        } else {
            (iy * gw + ix) as u32
        }
    };
    scratch.rows.clear();
    scratch.weights.clear();
    let kf = f64::from(k);
    for s in &scratch.samples {
        let [a, b, obs, i00, i01, i10, i11] = *s;
        // The blur segment in cell units of the padded grid (cell (0, 0) is [0, 1)^2),
        // walked cell by cell; each cell's weight is the share of the segment inside it.
        let (dx, dy) = ((i00 * u.x + i01 * u.y) / pa, (i10 * u.x + i11 * u.y) / pb);
        let (x0, y0) = (
            (a + 1.0) / pa + kf - 0.5 * dx,
            (b + 1.0) / pb + kf - 0.5 * dy,
        );
        let start = scratch.weights.len();
        let inside_grid =
            |x: f64, y: f64| x >= 0.0 && y >= 0.0 && x < f64::from(gw) && y < f64::from(gh);
        if !inside_grid(x0, y0) || !inside_grid(x0 + dx, y0 + dy) {
            continue;
        }
        // Truncation is the floor here: both ends are inside the grid, so non-negative.
        let (mut cx, mut cy) = (x0 as i32, y0 as i32);
        let crossing = |p0: f64, c: i32, d: f64| {
            if d > 0.0 {
                ((f64::from(c) + 1.0 - p0) / d, 1.0 / d, 1)
            } else if d < 0.0 {
                ((p0 - f64::from(c)) / -d, -1.0 / d, -1)
            } else {
                (f64::INFINITY, f64::INFINITY, 0)
            }
        };
        let (mut tx, step_tx, sx) = crossing(x0, cx, dx);
        let (mut ty, step_ty, sy) = crossing(y0, cy, dy);
        let mut t = 0.0;
        loop {
            let next = tx.min(ty).min(1.0);
            if next > t && (0..gw).contains(&cx) && (0..gh).contains(&cy) {
                scratch.weights.push((index(cx, cy), next - t));
            }
            if next >= 1.0 {
                break;
            }
            t = next;
            if tx <= ty {
                cx += sx;
                tx += step_tx;
            } else {
                cy += sy;
                ty += step_ty;
            }
        }
        let count = (scratch.weights.len() - start) as u32;
        scratch.rows.push((start as u32, count, obs));
    }
    let rows = &scratch.rows;
    if rows.len() < n / 2 {
        return None;
    }
    let weights = &scratch.weights;
    let row_w = |r: &(u32, u32, f64)| &weights[r.0 as usize..(r.0 + r.1) as usize];
    let mean = rows.iter().map(|r| r.2).sum::<f64>() / rows.len() as f64;
    // The envelope first (each row's first non-zero column: the lowest cell of every
    // segment that crosses the row's cell), then the lower triangle within it (the only
    // part the factorisation reads).
    scratch.first.clear();
    scratch.first.extend(0..n);
    let first = &mut scratch.first;
    for r in rows {
        let w = row_w(r);
        let lo = w.iter().map(|&(i, _)| i as usize).min().unwrap_or(0);
        for &(i, _) in w {
            let i = i as usize;
            first[i] = first[i].min(lo);
        }
    }
    let stored = envelope(first, &mut scratch.start, &mut scratch.last);
    scratch.ata.clear();
    scratch.ata.resize(stored.max(n), 0.0);
    scratch.atb.clear();
    scratch.atb.resize(n, 0.0);
    let (ata, atb) = (&mut scratch.ata, &mut scratch.atb);
    let (first, start, last) = (&scratch.first, &scratch.start, &scratch.last);
    // Per cell of the current sample row: where its row of `ata` starts (entry `(i, j)` at
    // `base[i] + j`).
    let mut base = [0usize; MAX_SEGMENT_CELLS];
    for r in rows {
        let w = row_w(r);
        let obs = r.2 - mean;
        if w.len() > MAX_SEGMENT_CELLS {
            for &(i, wi) in w {
                let i = i as usize;
                atb[i] += wi * obs;
                let row = start[i] - first[i];
                for &(j, wj) in w {
                    let j = j as usize;
                    if j <= i {
                        ata[row + j] += wi * wj;
                    }
                }
            }
            continue;
        }
        // A segment crosses each cell once, so every entry takes one product per sample
        // row whatever the order within the row: each pair of the row's cells once, into
        // the lower triangle (the row of the larger index), without a branch.
        for (b, &(i, _)) in base.iter_mut().zip(w) {
            *b = start[i as usize] - first[i as usize];
        }
        for (p, &(i, wi)) in w.iter().enumerate() {
            atb[i as usize] += wi * obs;
            let bi = base[p];
            for (&(j, wj), &bj) in w[..=p].iter().zip(&base[..=p]) {
                let at = if j <= i {
                    bi + j as usize
                } else {
                    bj + i as usize
                };
                ata[at] += wi * wj;
            }
        }
    }
    // A light ridge towards the mean keeps cells few samples see (the outer ring) defined.
    let ridge = 0.02 * 9.0;
    for i in 0..n {
        ata[start[i] + i - first[i]] += ridge;
    }
    if !cholesky_solve(ata, [first, start, last], atb, n) {
        return None;
    }
    let mut misfit = 0.0;
    for r in rows {
        let m: f64 = row_w(r).iter().map(|&(i, wi)| wi * atb[i as usize]).sum();
        misfit += (m - (r.2 - mean)).powi(2);
    }
    // Back to row major (`ata` is free now) and to grey levels.
    if column_major {
        ata[..n].copy_from_slice(&atb[..n]);
        for iy in 0..gh {
            for ix in 0..gw {
                atb[(iy * gw + ix) as usize] = ata[(ix * gh + iy) as usize];
            }
        }
    }
    for v in atb.iter_mut() {
        *v += mean;
    }
    Some(misfit / rows.len() as f64)
}

/// Most cells of one blur segment whose normal-matrix entries [`solve_levels`] adds
/// without a branch per pair (a longer one, which no motion of the model crosses, takes
/// the plain loop).
const MAX_SEGMENT_CELLS: usize = 32;

/// Most border and quiet-zone cells (a 10 x 10 marker).
const MAX_RING: usize = 4 * 12;

/// The reading of solved `levels` (cells `-k..w + k` by `-k..h + k`), as
/// [`crate::decode::read_cells_with`] reads sampled ones.
fn reading(
    levels: &[f64],
    k: i32,
    family: MarkerFamily,
    white: WhiteReference,
    params: &DecodeParams,
) -> Option<CellReading> {
    let (wc, hc) = (family.width_cells() as i32, family.height_cells() as i32);
    let gw = wc + 2 * k;
    let at = |x: i32, y: i32| levels.get(((y + k) * gw + x + k) as usize).copied();
    let mut border = [0.0f64; MAX_RING];
    let mut quiet = [0.0f64; MAX_RING];
    let (mut nb, mut nq) = (0, 0);
    for y in -1..=hc {
        for x in -1..=wc {
            let ring = x == -1 || y == -1 || x == wc || y == hc;
            let edge = x == 0 || y == 0 || x == wc - 1 || y == hc - 1;
            if ring {
                *quiet.get_mut(nq)? = at(x, y)?;
                nq += 1;
            } else if edge {
                *border.get_mut(nb)? = at(x, y)?;
                nb += 1;
            }
        }
    }
    let (m, n) = (family.rows() as i32, family.cols() as i32);
    let mut data = [0.0f64; 64];
    for r in 0..m {
        for c in 0..n {
            data[(r * n + c) as usize] = at(c + 1, r + 1)?;
        }
    }
    reading_from_levels(
        &mut border[..nb],
        &mut quiet[..nq],
        &data,
        (m * n) as usize,
        white,
        params,
    )
    .ok()
}

/// Reads the quad `corners` (clockwise in the image) as a motion-blurred marker of one of
/// `dictionaries` (see the module documentation): the decoded marker, or `None`.
pub(crate) fn decode_blurred(
    image: &GrayView<'_>,
    corners: &Corners,
    dictionaries: &[Dictionary],
    params: &DecodeParams,
    scratch: &mut BlurScratch,
) -> Option<Decoded> {
    let mut us = [Vector2::zeros(); MAX_MOTIONS];
    let (count, length) = motions(image, corners, &mut us);
    if count == 0 {
        return None;
    }
    // The smear of the outline: a motion of length `L` spreads the border's darkness at
    // least `0.28 L` outside the side most across it, whatever lies inside the quad, while a
    // sharp edge reaches about 1.5 px. A quad whose outline reaches less on every side is
    // not smeared by the motion its step widths suggest (those can come from edges inside
    // it), and its systems are not solved (see [`MIN_BLUR_SMEAR`]).
    let smeared = (0..4)
        .filter_map(|i| outer_reach(image, corners, i, 0.6 * length + 3.0))
        .fold(0.0, f64::max);
    if smeared < (MIN_SMEAR_FRACTION * length).max(MIN_BLUR_SMEAR) {
        return None;
    }
    let us = &us[..count];
    let exact = DecodeParams {
        max_errors: 0,
        ..*params
    };
    let side = (0..4)
        .map(|i| (corners[(i + 1) % 4] - corners[i]).norm())
        .fold(f64::INFINITY, f64::min);
    let mut best: Option<Decoded> = None;
    let mut counted = false;
    for (di, dict) in dictionaries.iter().enumerate() {
        let family = dict.family();
        let shifts: &[u8] = if family.is_square() { &[0] } else { &[0, 1] };
        let white = WhiteReference::of(dict);
        let pitch = side / f64::from(family.width_cells().max(family.height_cells()));
        // A box blur of length `L` (in cells) centred on a cell's centre keeps at least
        // `1 - 1 / (2 L)` of that cell's own level, more than half for any `L < 2`: the
        // plain reading, which thresholds the centre samples midway between black and
        // white, reads such a cell right up to noise. Below 1.5 cells (two thirds of its
        // own level, a third of the contrast as margin) the model has nothing to add, and
        // a quad that is not a marker is not worth its cost.
        if length < MIN_MOTION_CELLS * pitch || pitch < MIN_BLUR_PITCH {
            continue;
        }
        if !counted {
            counted = true;
            scratch.solved_quads += 1;
        }
        for &s in shifts {
            let frame_corners: Corners = core::array::from_fn(|i| corners[(i + s as usize) % 4]);
            let Ok(frame) = CrossRatioFrame::new(&frame_corners) else {
                continue;
            };
            if !gather_samples(image, &frame, family, scratch) {
                continue;
            }
            // The candidate motion that explains the samples best: its levels are kept in
            // `scratch.best`. Each sign is solved at its estimated length first, then the
            // better sign alone at its shorter and longer lengths (4 solves rather than 6:
            // on the motion-blur scenes the sign chosen at the estimate was the final
            // one's for all but 3 of some 2,000 markers).
            let mut best_fit: Option<(f64, i32, usize)> = None;
            for ui in (1..us.len()).step_by(3) {
                fit_motion(us, ui, family, pitch, scratch, &mut best_fit);
            }
            // A quad the model leaves much of unexplained at the estimated motion is no
            // blurred marker of this grid: the shorter and longer motions are not tried and
            // nothing is read.
            if best_fit.is_some_and(|(m, _, _)| m > MAX_UNEXPLAINED * sample_variance(scratch)) {
                continue;
            }
            if let Some((_, _, b)) = best_fit {
                fit_motion(us, b - 1, family, pitch, scratch, &mut best_fit);
                fit_motion(us, b + 1, family, pitch, scratch, &mut best_fit);
            }
            let Some((_, k, _)) = best_fit else {
                continue;
            };
            let Some(r) = reading(&scratch.best, k, family, white, &exact) else {
                continue;
            };
            match match_reading(corners, s, &r, dict, &exact) {
                Some(mut d) => {
                    if best.is_none_or(|b| d.distance < b.distance) {
                        d.dictionary = di;
                        best = Some(d);
                    }
                }
                None => scratch.unmatched.push((di, s, r)),
            }
        }
    }
    // The least-cost reading only where the quad's own outline shows the smear: on sharp
    // clutter the step widths can read a long motion from edges inside the quad.
    if best.is_none()
        && !scratch.unmatched.is_empty()
        && smeared >= (MIN_SMEAR_FRACTION * length).max(MIN_SMEAR)
    {
        best = least_cost_match(corners, dictionaries, &scratch.unmatched);
    }
    scratch.unmatched.clear();
    best
}

/// Most mean squared misfit of the better sign's solve at the estimated motion, as a share
/// of the samples' variance, for the blurred reading to go on ([`decode_blurred`]). Our
/// own dictionary's markers read on the motion-blur rows of `cargo xtask detector-accuracy
/// --motion-blur` (3-13 px) were explained to within 0.04 of their variance, and a bound
/// of 0.08 kept every one of them; but tag36h11's larger grid leaves more: on fresh
/// tag36h11 scenes of the held-out sets' kind (`cargo xtask motion-sets` at seeds 61,000
/// on, 20 scenes a set) the markers read left up to 0.118 unexplained (95 % under 0.078),
/// and at 0.08 `motion-sets` lost 12 of its tag36h11 markers (regression test
/// `the_early_stop_keeps_the_tag36h11_markers_it_can_read`). At 0.15 those sets and
/// scenes read what they read with no early stop. The quads of the real photos that reach
/// the solves (none a marker) leave 0.02-0.16 unexplained, so the bound now spares only
/// the worst of them their last two solves.
const MAX_UNEXPLAINED: f64 = 0.15;

/// The variance of the grey levels in `scratch.samples` (0 when there are none).
fn sample_variance(scratch: &BlurScratch) -> f64 {
    let n = scratch.samples.len() as f64;
    if n == 0.0 {
        return 0.0;
    }
    let mean = scratch.samples.iter().map(|x| x[2]).sum::<f64>() / n;
    scratch
        .samples
        .iter()
        .map(|x| (x[2] - mean).powi(2))
        .sum::<f64>()
        / n
}

/// Solves the levels for candidate motion `us[ui]` ([`solve_levels`]) and keeps them in
/// `scratch.best` when they explain the samples better than `best_fit` (misfit, padding
/// `k`, index into `us`), which is then updated.
fn fit_motion(
    us: &[Vector2<f64>],
    ui: usize,
    family: MarkerFamily,
    pitch: f64,
    scratch: &mut BlurScratch,
    best_fit: &mut Option<(f64, i32, usize)>,
) {
    let Some(&u) = us.get(ui) else {
        return;
    };
    let k = (1.0 + (0.5 * u.norm() / pitch.max(1.0)).ceil()).min(4.0) as i32;
    let Some(misfit) = solve_levels(family, u, k, scratch) else {
        return;
    };
    if best_fit.is_none_or(|(m, _, _)| misfit < m) {
        *best_fit = Some((misfit, k, ui));
        scratch.best.clear();
        scratch.best.extend_from_slice(&scratch.atb);
    }
}

/// Least [`outer_reach`] (over the four sides) of a quad read by [`least_cost_match`], as a
/// fraction of the estimated motion length: the side most across a motion of length `L`
/// reaches at least `0.4 L cos 45` = `0.28 L` out.
const MIN_SMEAR_FRACTION: f64 = 0.2;

/// ...and at least this many pixels (a sharp edge reaches about 1.5 px).
const MIN_SMEAR: f64 = 2.5;

/// Least [`outer_reach`] (over the four sides, pixels) of any quad read as motion-blurred:
/// beyond the 1.5 px of a sharp edge under the optical blur (outer reaches are measured in
/// half pixels). With [`MIN_SMEAR_FRACTION`] of the motion, this is checked before any
/// system is solved. On the motion-blur scenes (seeds 90,000-90,009, 3-13 px) every
/// marker the blurred reading read reached at least 2.5 px and 0.35 of the estimated
/// motion; of the 15 quads of the real photos (`cargo xtask photos`, none a marker) that
/// reached the solves, 4 reached less (0-1.5 px) and are no longer solved.
const MIN_BLUR_SMEAR: f64 = 2.0;

/// Most summed margin of the cells a [`least_cost_match`] flips (in half contrasts).
const MAX_FLIP_COST: f64 = 0.4;

/// Least summed margin by which the next best entry's flips must cost more.
const MIN_FLIP_GAP: f64 = 0.3;

/// The entry that the blurred readings `unmatched` (dictionary, corner shift, reading)
/// come closest to when a flipped cell costs its margin, if it is clearly the one.
///
/// The hard and soft lookups of [`match_reading`] flip at most the two least confident
/// cells. A cell read from the least-squares levels of a long motion is not independent
/// of its neighbours, though: the box blur's spectral zero leaves patterns of cell levels
/// that the samples barely constrain, and the cells that read wrong are then the weak ones
/// but not always the two weakest. Flipping a cell whose level lies a margin `m` (in half
/// contrasts) from the threshold costs `m` (the log-likelihood ratio of the two levels
/// under Gaussian noise, up to a common scale), so the entry whose differing cells cost
/// least is the most likely one. It is accepted only within the dictionary's correction
/// radius, at a total cost of at most [`MAX_FLIP_COST`], and when every other entry, under
/// either grid shift and any turn, costs at least [`MIN_FLIP_GAP`] more: a reading that
/// could be two entries is not read.
fn least_cost_match(
    corners: &Corners,
    dictionaries: &[Dictionary],
    unmatched: &[(usize, u8, CellReading)],
) -> Option<Decoded> {
    // (cost, position in `unmatched`, match) of the cheapest entry, and the cost of the
    // cheapest other entry.
    let mut best: Option<(f64, usize, Match)> = None;
    let mut second = f64::INFINITY;
    for (u, (di, _, r)) in unmatched.iter().enumerate() {
        let Some(dict) = dictionaries.get(*di) else {
            continue;
        };
        let family = dict.family();
        for (index, rotated) in dict.rotated_codes().iter().enumerate() {
            // The cheapest turn of this entry.
            let mut entry: Option<(f64, Match)> = None;
            for &q in family.symmetries() {
                let code = rotated[q as usize];
                let diff = code ^ r.code;
                let flips = diff.count_ones();
                let mut cost = 0.0;
                let mut bits = diff;
                while bits != 0 {
                    cost += r.margin(bits.trailing_zeros() as usize);
                    bits &= bits - 1;
                }
                if entry.is_none_or(|(c, _)| cost < c) {
                    let m = Match {
                        index,
                        code: rotated[0],
                        distance: flips,
                        rotation: q,
                    };
                    entry = Some((cost, m));
                }
            }
            let Some((cost, m)) = entry else {
                continue;
            };
            // The same entry under the other shift is the same reading, not a rival.
            let same = best.is_some_and(|(_, bu, bm)| bm.index == index && unmatched[bu].0 == *di);
            match best {
                Some((c, _, _)) if cost >= c => {
                    if !same {
                        second = second.min(cost);
                    }
                }
                Some((c, _, _)) if !same => {
                    second = second.min(c);
                    best = Some((cost, u, m));
                }
                _ => best = Some((cost, u, m)),
            }
        }
    }
    let (cost, u, m) = best?;
    let max_flips = dictionaries
        .get(unmatched[u].0)
        .map_or(0, Dictionary::max_correctable);
    if !(m.distance <= max_flips && cost <= MAX_FLIP_COST && second - cost >= MIN_FLIP_GAP) {
        return None;
    }
    let (di, s, r) = &unmatched[u];
    let mut d = decoded_from_match(corners, *s, r, &m);
    d.dictionary = *di;
    Some(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reading of the paper dictionary's entry `index` (turned `q`) with the cells
    /// `flipped` read wrong, each cell at the margin given by `margins` (cell, margin; the
    /// others at margin 1): black 0, white 200.
    fn reading_of(index: usize, q: u8, flipped: &[usize], margins: &[(usize, f64)]) -> CellReading {
        let dict = Dictionary::paper();
        let mut code = dict.rotated_codes()[index][q as usize];
        for &b in flipped {
            code ^= 1 << b;
        }
        let mut levels = [0.0; 64];
        for (k, l) in levels
            .iter_mut()
            .enumerate()
            .take(dict.family().bits() as usize)
        {
            let m = margins
                .iter()
                .find(|(c, _)| *c == k)
                .map_or(1.0, |(_, m)| *m);
            // Dark cells below the midpoint, light above, at the margin given.
            *l = if code & (1 << k) != 0 {
                100.0 - 100.0 * m
            } else {
                100.0 + 100.0 * m
            };
        }
        CellReading {
            code,
            black: 0.0,
            white: 200.0,
            light_border_cells: 0,
            confidence: 0.0,
            fit: 1.0,
            levels,
        }
    }

    fn square() -> Corners {
        [
            Point2::new(10.0, 10.0),
            Point2::new(40.0, 10.0),
            Point2::new(40.0, 40.0),
            Point2::new(10.0, 40.0),
        ]
    }

    /// Two cells read wrong, neither among the two least confident (which the soft lookup
    /// would try), but cheap: the entry is read; too dear, or beyond the correction
    /// radius however cheap, it is not.
    /// A 64 x 64 image whose grey level depends on x alone, with the quad side 0 running
    /// down x = 32 (from y = 10 to y = 50): the profile `level(x)` across that side.
    fn across_side(level: impl Fn(f64) -> f64) -> (Vec<u8>, Corners) {
        let px: Vec<u8> = (0..64 * 64)
            .map(|i| level((i % 64) as f64).round().clamp(0.0, 255.0) as u8)
            .collect();
        let corners = [
            Point2::new(32.0, 10.0),
            Point2::new(32.0, 50.0),
            Point2::new(0.0, 50.0),
            Point2::new(0.0, 10.0),
        ];
        (px, corners)
    }

    #[test]
    fn a_motion_ramp_reads_as_a_ramp_and_two_sharp_steps_do_not() {
        // An edge smeared by an 8 px motion across it: a linear ramp.
        let (px, c) = across_side(|x| 200.0 - 160.0 * ((x - 28.0) / 8.0).clamp(0.0, 1.0));
        let img = GrayView::new(&px, 64, 64).expect("valid image");
        let (width, peak) = step_width(&img, &c, 0).expect("a step");
        assert!((width - 8.0).abs() < 1.5, "ramp width {width}");
        assert!(peak < 0.8 * MAX_RAMP_PEAK, "ramp peakedness {peak}");
        // A sharp border 4 px wide with a light cell behind it (a sharp quad whose cell edge
        // lies within the profile): about as wide by the spread, but two spikes.
        let (px, c) = across_side(|x| {
            if (32.0..36.0).contains(&x) {
                40.0
            } else {
                200.0
            }
        });
        let img = GrayView::new(&px, 64, 64).expect("valid image");
        let (width, peak) = step_width(&img, &c, 0).expect("a step");
        assert!(width > 3.0, "two steps read as a wide step: {width}");
        assert!(peak > MAX_RAMP_PEAK, "two sharp steps' peakedness {peak}");
    }

    #[test]
    fn least_cost_match_reads_cheap_flips_within_the_correction_radius_only() {
        let dicts = [Dictionary::paper().clone()];
        let weak = [(0, 0.02), (1, 0.03), (7, 0.1), (12, 0.15)];
        let r = reading_of(5, 2, &[7, 12], &weak);
        let d = least_cost_match(&square(), &dicts, &[(0, 0, r)]).expect("read");
        assert_eq!((d.index, d.distance), (5, 2));
        assert!(
            match_reading(
                &square(),
                0,
                &r,
                &dicts[0],
                &DecodeParams {
                    max_errors: 0,
                    soft_errors: 2,
                    soft_margin: 0.3,
                    ..DecodeParams::default()
                }
            )
            .is_none(),
            "the soft lookup alone reads it: the test shows nothing"
        );
        // The same flips at margins costing 0.5 in all: not read.
        let dear = reading_of(
            5,
            2,
            &[7, 12],
            &[(0, 0.02), (1, 0.03), (7, 0.25), (12, 0.25)],
        );
        assert!(least_cost_match(&square(), &dicts, &[(0, 0, dear)]).is_none());
        // Three flips costing 0.15 in all: beyond the radius of 2, not read.
        let three = reading_of(5, 2, &[3, 7, 12], &[(3, 0.05), (7, 0.05), (12, 0.05)]);
        assert!(least_cost_match(&square(), &dicts, &[(0, 0, three)]).is_none());
    }

    /// A second grid shift that reads another entry almost as cheaply: neither is read;
    /// the same entry under both shifts is no rival.
    #[test]
    fn least_cost_match_refuses_a_reading_that_could_be_two_entries() {
        let dicts = [Dictionary::paper().clone()];
        let a = reading_of(5, 0, &[7, 12], &[(7, 0.1), (12, 0.15)]);
        let b = reading_of(9, 2, &[2, 4], &[(2, 0.15), (4, 0.15)]);
        assert!(least_cost_match(&square(), &dicts, &[(0, 0, a), (0, 1, b)]).is_none());
        let b_far = reading_of(9, 2, &[2, 4], &[(2, 0.4), (4, 0.4)]);
        let d = least_cost_match(&square(), &dicts, &[(0, 0, a), (0, 1, b_far)]).expect("read");
        assert_eq!(d.index, 5);
        let same = reading_of(5, 2, &[3], &[(3, 0.2)]);
        let d = least_cost_match(&square(), &dicts, &[(0, 0, a), (0, 1, same)]).expect("read");
        assert_eq!(d.index, 5);
    }

    /// A quad whose cells are under [`MIN_BLUR_PITCH`] is not solved for even when every
    /// other gate lets it through (a motion of over 1.5 cells, a ramp, a smeared outline);
    /// the same marker and motion with cells of 3 px is. Each is rendered five times larger,
    /// smeared by 2.5 cells along x and reduced by 5 x 5 block means (cells of 1.4 and 3 px).
    #[test]
    fn cells_under_the_least_pitch_are_not_solved_for() {
        let dict = Dictionary::paper();
        let family = dict.family();
        const F: usize = 5;
        for cell in [7u32, 15] {
            let options = crate::RenderOptions {
                px_per_cell: cell,
                quiet_cells: 6,
            };
            let m = crate::render_marker(family, dict.codes()[3], &options).expect("rendered");
            let (w, h) = (m.width(), m.height());
            let length = (2.5 * f64::from(cell)).round();
            let smeared =
                marker_testkit::motion_blur(m.pixels(), w, h, length, 0.0).expect("blurred");
            let (sw, sh) = (w / F, h / F);
            let px: Vec<u8> = (0..sw * sh)
                .map(|i| {
                    let (x, y) = (i % sw, i / sw);
                    let sum: f64 = (0..F * F)
                        .map(|k| f64::from(smeared[(F * y + k / F) * w + F * x + k % F]))
                        .sum();
                    (sum / (F * F) as f64).round() as u8
                })
                .collect();
            let img = GrayView::new(&px, sw, sh).expect("valid image");
            let half = 0.5 * (F as f64 - 1.0);
            let corners = m
                .corners()
                .map(|c| Point2::new((c.x - half) / F as f64, (c.y - half) / F as f64));
            let pitch = f64::from(cell) / F as f64;
            let mut us = [Vector2::zeros(); MAX_MOTIONS];
            let (count, length) = motions(&img, &corners, &mut us);
            assert!(
                count > 0 && length >= MIN_MOTION_CELLS * pitch,
                "{pitch} px: {length}"
            );
            let smear = (0..4)
                .filter_map(|i| outer_reach(&img, &corners, i, 0.6 * length + 3.0))
                .fold(0.0, f64::max);
            assert!(
                smear >= (MIN_SMEAR_FRACTION * length).max(MIN_BLUR_SMEAR),
                "{pitch} px: {smear}"
            );
            let mut scratch = BlurScratch::default();
            let params = DecodeParams::default();
            decode_blurred(
                &img,
                &corners,
                std::slice::from_ref(dict),
                &params,
                &mut scratch,
            );
            assert_eq!(scratch.solved_quads > 0, cell == 15, "{pitch} px");
        }
    }

    /// The envelope factorisation solves what a dense one does: a symmetric positive
    /// definite matrix whose rows start at varied columns (as the blur systems' do).
    #[test]
    fn envelope_cholesky_matches_a_dense_solve() {
        let n: usize = 23;
        let first: Vec<usize> = (0..n).map(|i| i.saturating_sub(1 + (i * 7) % 6)).collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in first[i]..i {
                let v = ((i * 31 + j * 17) % 11) as f64 / 11.0 - 0.5;
                a[i * n + j] = v;
                a[j * n + i] = v;
            }
            a[i * n + i] = 4.0 + (i % 3) as f64;
        }
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
        let dense = nalgebra::DMatrix::from_row_slice(n, n, &a);
        let x = dense
            .clone()
            .cholesky()
            .expect("diagonally dominant")
            .solve(&nalgebra::DVector::from_column_slice(&b));
        let mut got = b.clone();
        // The lower triangle of the envelope, row by row.
        let (mut start, mut last) = (Vec::new(), Vec::new());
        envelope(&first, &mut start, &mut last);
        let mut env: Vec<f64> = (0..n)
            .flat_map(|i| a[i * n + first[i]..=i * n + i].to_vec())
            .collect();
        assert!(cholesky_solve(
            &mut env,
            [&first, &start, &last],
            &mut got,
            n
        ));
        for i in 0..n {
            assert!(
                (got[i] - x[i]).abs() < 1e-12,
                "x[{i}]: {} vs {}",
                got[i],
                x[i]
            );
        }
        // Not positive definite: refused, not NaN (rows [1], [0, -1]).
        let mut bad = vec![1.0, 0.0, -1.0];
        let mut rhs = vec![1.0, 1.0];
        assert!(!cholesky_solve(
            &mut bad,
            [&[0, 0], &[0, 1], &[1, 1]],
            &mut rhs,
            2
        ));
    }
}
