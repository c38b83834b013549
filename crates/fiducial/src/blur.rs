//! Reading a quad whose cells are smeared by motion blur (issue #16).
//!
//! A camera moving while the shutter is open smears the image along one direction: every
//! pixel is the mean of the sharp image along a segment `u` (the motion during the
//! exposure, pixels). Edges along the motion stay sharp, edges across it become ramps of
//! the blur length, and on a small marker a dark cell bleeds into its light neighbours until
//! the cell centres no longer read right.
//!
//! When the plain reading of a quad is not a dictionary entry, the detector calls
//! [`decode_blurred`]: the motion is estimated from the quad's own edges (the spread of the
//! grey-level step across each side is the optical blur plus the motion's component along
//! the side's normal), and for each candidate motion the grid's cell levels (the marker,
//! its quiet zone and the cells around) are solved by least squares from samples inside
//! every cell, each modelled as the mean of the cells its blur segment crosses. The
//! candidate that explains the samples best gives the levels, which are read as
//! [`crate::decode::read_cells`] reads sampled levels. Hard bit correction is off (as in
//! the default detector); the soft decision of [`DecodeParams`] applies.

use nalgebra::{Point2, Vector2};

use crate::cross_ratio::CrossRatioFrame;
use crate::decode::{
    CellReading, DecodeParams, Decoded, WhiteReference, match_reading, reading_from_levels,
};
use crate::dictionary::Dictionary;
use crate::family::MarkerFamily;
use crate::image::{Corners, GrayView};

/// Optical blur assumed under the motion (variance of the step's derivative, px^2): the
/// renderer's blur sigma 1 and the pixel's own width.
const OPTICAL_VARIANCE: f64 = 1.1;

/// Shortest motion worth modelling, pixels.
const MIN_MOTION: f64 = 1.5;

/// Bilinear grey level at `p`, `None` outside the image.
fn bilinear(image: &GrayView<'_>, p: Point2<f64>) -> Option<f64> {
    let (w, h) = (image.width(), image.height());
    if !(p.x >= 0.0 && p.y >= 0.0 && p.x <= (w - 1) as f64 && p.y <= (h - 1) as f64) {
        return None;
    }
    let (x0, y0) = (p.x.floor() as usize, p.y.floor() as usize);
    let (fx, fy) = (p.x - x0 as f64, p.y - y0 as f64);
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    let (r0, r1) = (image.row(y0), image.row(y1));
    let top = f64::from(r0[x0]) * (1.0 - fx) + f64::from(r0[x1]) * fx;
    let bottom = f64::from(r1[x0]) * (1.0 - fx) + f64::from(r1[x1]) * fx;
    Some(top * (1.0 - fy) + bottom * fy)
}

/// Width of the step across side `i` (corners `i` to `i + 1`) beyond the optical blur: the
/// motion's component along the side's normal, pixels (`None` when no step is measured).
fn step_width(image: &GrayView<'_>, corners: &Corners, i: usize) -> Option<f64> {
    let (p, q) = (corners[i], corners[(i + 1) % 4]);
    let along = q - p;
    let len = along.norm();
    if len.is_nan() || len <= 4.0 {
        return None;
    }
    let n = Vector2::new(along.y, -along.x) / len;
    let reach = (0.6 * len / 4.0).clamp(3.0, 10.0);
    let (mut sw, mut s1, mut s2) = (0.0, 0.0, 0.0);
    for k in 1..8 {
        let base = p + along * (f64::from(k) / 8.0);
        let mut prev: Option<f64> = None;
        let mut t = -reach;
        while t <= reach {
            let v = bilinear(image, base + n * t);
            if let (Some(a), Some(b)) = (prev, v) {
                // Either polarity: the side's outward direction is not known here.
                let d = (b - a).abs();
                let tm = t - 0.25;
                sw += d;
                s1 += d * tm;
                s2 += d * tm * tm;
            }
            prev = v;
            t += 0.5;
        }
    }
    if sw.is_nan() || sw <= 0.0 {
        return None;
    }
    let mean = s1 / sw;
    let var = s2 / sw - mean * mean;
    Some((12.0 * (var - OPTICAL_VARIANCE).max(0.0)).sqrt())
}

/// Most candidate motions: two sign choices at three scales, and eight directions at two.
const MAX_MOTIONS: usize = 2 * 3 + 8 * 2;

/// Candidate motions of `corners` into `out` (the count is returned): from the step widths
/// across two adjacent sides (two sign choices), each also 25 % shorter and longer.
fn motions(
    image: &GrayView<'_>,
    corners: &Corners,
    out: &mut [Vector2<f64>; MAX_MOTIONS],
) -> usize {
    let w: [Option<f64>; 4] = core::array::from_fn(|i| step_width(image, corners, i));
    let pair = |a: usize, b: usize| match (w[a], w[b]) {
        (Some(x), Some(y)) => Some(0.5 * (x + y)),
        (Some(x), None) | (None, Some(x)) => Some(x),
        _ => None,
    };
    let (Some(b0), Some(b1)) = (pair(0, 2), pair(1, 3)) else {
        return 0;
    };
    let normal = |i: usize| {
        let d = corners[(i + 1) % 4] - corners[i];
        Vector2::new(d.y, -d.x) / d.norm()
    };
    let m = nalgebra::Matrix2::from_rows(&[normal(0).transpose(), normal(1).transpose()]);
    let Some(inv) = m.try_inverse() else {
        return 0;
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
    // The step widths are rough (noise, neighbouring cells within reach): a coarse search
    // over directions at the estimated length as well.
    if length >= MIN_MOTION {
        for i in 0..8 {
            let angle = f64::from(i) * std::f64::consts::PI / 8.0;
            let dir = Vector2::new(angle.cos(), angle.sin());
            for scale in [0.8, 1.1] {
                out[n] = dir * length * scale;
                n += 1;
            }
        }
    }
    n
}

/// Scratch space of the blurred reading, owned by the detector so that a steady stream of
/// frames reads blurred markers without touching the heap: buffers grow to the largest
/// system solved and are reused.
#[derive(Debug, Clone, Default)]
pub(crate) struct BlurScratch {
    /// Normal matrix (row major, `n x n`), factored in place.
    ata: Vec<f64>,
    /// Right-hand side, then the solution.
    atb: Vec<f64>,
    /// Per sample row: its first weight in `weights`, its weight count and its grey level.
    rows: Vec<(u32, u32, f64)>,
    /// Cell index and weight of every row's blur segment.
    weights: Vec<(u32, f64)>,
    /// Levels of the best candidate so far (and their `k`, misfit).
    best: Vec<f64>,
}

/// Solves `a x = b` in place for a symmetric positive definite `a` (`n x n`, row major):
/// Cholesky factor into the lower triangle of `a`, then `b` becomes `x`. `false` if `a` is
/// not positive definite.
fn cholesky_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut v = a[i * n + j];
            for k in 0..j {
                v -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = v / d;
        }
    }
    // L y = b, then L^T x = y.
    for i in 0..n {
        let mut v = b[i];
        for k in 0..i {
            v -= a[i * n + k] * b[k];
        }
        b[i] = v / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut v = b[i];
        for k in i + 1..n {
            v -= a[k * n + i] * b[k];
        }
        b[i] = v / a[i * n + i];
    }
    b.iter().all(|v| v.is_finite())
}

/// Solves the cell levels of the grid of `family` under `corners` (taken as NW, NE, SE,
/// SW) for the motion `u` into `scratch.atb` (levels of cells `-k..w + k` by `-k..h + k`),
/// and returns the mean squared misfit of the samples; `None` when the frame or the system
/// cannot be built.
fn solve_levels(
    image: &GrayView<'_>,
    frame: &CrossRatioFrame,
    family: MarkerFamily,
    u: Vector2<f64>,
    k: i32,
    scratch: &mut BlurScratch,
) -> Option<f64> {
    let (wc, hc) = (family.width_cells() as i32, family.height_cells() as i32);
    let (gw, gh) = (wc + 2 * k, hc + 2 * k);
    let n = (gw * gh) as usize;
    scratch.rows.clear();
    scratch.weights.clear();
    const SEG: usize = 16;
    let offs = [-1.0 / 3.0, 0.0, 1.0 / 3.0];
    let (pa, pb) = (2.0 / f64::from(wc), 2.0 / f64::from(hc));
    for cy in -1..=hc {
        for cx in -1..=wc {
            for oy in offs {
                for ox in offs {
                    let a = -1.0 + (f64::from(cx) + 0.5 + ox) * pa;
                    let b = -1.0 + (f64::from(cy) + 0.5 + oy) * pb;
                    let p = frame.map(a, b)?;
                    let Some(obs) = bilinear(image, p) else {
                        continue;
                    };
                    let e = 1e-3;
                    let ja = (frame.map(a + e, b)? - p) / e;
                    let jb = (frame.map(a, b + e)? - p) / e;
                    let j = nalgebra::Matrix2::from_columns(&[ja, jb]);
                    let d = j.try_inverse()? * u;
                    let start = scratch.weights.len();
                    let mut inside = true;
                    for s in 0..SEG {
                        let t = -0.5 + (s as f64 + 0.5) / SEG as f64;
                        let (aa, bb) = (a + t * d.x, b + t * d.y);
                        let ix = ((aa + 1.0) / pa).floor() as i32 + k;
                        let iy = ((bb + 1.0) / pb).floor() as i32 + k;
                        if !(0..gw).contains(&ix) || !(0..gh).contains(&iy) {
                            inside = false;
                            break;
                        }
                        let idx = (iy * gw + ix) as u32;
                        match scratch.weights[start..].iter_mut().find(|(c, _)| *c == idx) {
                            Some(e) => e.1 += 1.0 / SEG as f64,
                            None => scratch.weights.push((idx, 1.0 / SEG as f64)),
                        }
                    }
                    if inside {
                        let count = (scratch.weights.len() - start) as u32;
                        scratch.rows.push((start as u32, count, obs));
                    } else {
                        scratch.weights.truncate(start);
                    }
                }
            }
        }
    }
    let rows = &scratch.rows;
    if rows.len() < n / 2 {
        return None;
    }
    let weights = &scratch.weights;
    let row_w = |r: &(u32, u32, f64)| &weights[r.0 as usize..(r.0 + r.1) as usize];
    let mean = rows.iter().map(|r| r.2).sum::<f64>() / rows.len() as f64;
    scratch.ata.clear();
    scratch.ata.resize(n * n, 0.0);
    scratch.atb.clear();
    scratch.atb.resize(n, 0.0);
    let (ata, atb) = (&mut scratch.ata, &mut scratch.atb);
    for r in rows {
        for &(i, wi) in row_w(r) {
            atb[i as usize] += wi * (r.2 - mean);
            for &(j, wj) in row_w(r) {
                ata[i as usize * n + j as usize] += wi * wj;
            }
        }
    }
    // A light ridge towards the mean keeps cells few samples see (the outer ring) defined.
    let ridge = 0.02 * 9.0;
    for i in 0..n {
        ata[i * n + i] += ridge;
    }
    if !cholesky_solve(ata, atb, n) {
        return None;
    }
    let mut misfit = 0.0;
    for r in rows {
        let m: f64 = row_w(r).iter().map(|&(i, wi)| wi * atb[i as usize]).sum();
        misfit += (m - (r.2 - mean)).powi(2);
    }
    for v in atb.iter_mut() {
        *v += mean;
    }
    Some(misfit / rows.len() as f64)
}

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
    let count = motions(image, corners, &mut us);
    if count == 0 {
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
    for (di, dict) in dictionaries.iter().enumerate() {
        let family = dict.family();
        let shifts: &[u8] = if family.is_square() { &[0] } else { &[0, 1] };
        let white = WhiteReference::of(dict);
        let pitch = side / f64::from(family.width_cells().max(family.height_cells()));
        for &s in shifts {
            let frame_corners: Corners = core::array::from_fn(|i| corners[(i + s as usize) % 4]);
            let Ok(frame) = CrossRatioFrame::new(&frame_corners) else {
                continue;
            };
            // The candidate motion that explains the samples best: its levels are kept in
            // `scratch.best`.
            let mut best_fit: Option<(f64, i32)> = None;
            for u in us {
                let k = (1.0 + (0.5 * u.norm() / pitch.max(1.0)).ceil()).min(4.0) as i32;
                let Some(misfit) = solve_levels(image, &frame, family, *u, k, scratch) else {
                    continue;
                };
                if best_fit.is_none_or(|(m, _)| misfit < m) {
                    best_fit = Some((misfit, k));
                    scratch.best.clear();
                    scratch.best.extend_from_slice(&scratch.atb);
                }
            }
            let Some((_, k)) = best_fit else {
                continue;
            };
            let Some(r) = reading(&scratch.best, k, family, white, &exact) else {
                continue;
            };
            if let Some(mut d) = match_reading(corners, s, &r, dict, &exact)
                && best.is_none_or(|b| d.distance < b.distance)
            {
                d.dictionary = di;
                best = Some(d);
            }
        }
    }
    best
}
