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

use nalgebra::{DMatrix, DVector, Point2, Vector2};

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

/// Candidate motions of `corners`: from the step widths across two adjacent sides (two
/// sign choices), each also 25 % shorter and longer.
fn motions(image: &GrayView<'_>, corners: &Corners) -> Vec<Vector2<f64>> {
    let w: Vec<Option<f64>> = (0..4).map(|i| step_width(image, corners, i)).collect();
    let pair = |a: usize, b: usize| match (w[a], w[b]) {
        (Some(x), Some(y)) => Some(0.5 * (x + y)),
        (Some(x), None) | (None, Some(x)) => Some(x),
        _ => None,
    };
    let (Some(b0), Some(b1)) = (pair(0, 2), pair(1, 3)) else {
        return Vec::new();
    };
    let normal = |i: usize| {
        let d = corners[(i + 1) % 4] - corners[i];
        Vector2::new(d.y, -d.x) / d.norm()
    };
    let m = nalgebra::Matrix2::from_rows(&[normal(0).transpose(), normal(1).transpose()]);
    let Some(inv) = m.try_inverse() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    let mut length = 0.0f64;
    for sign in [1.0, -1.0] {
        let u = inv * Vector2::new(b0, sign * b1);
        if !(u.norm() >= MIN_MOTION && u.norm().is_finite()) {
            continue;
        }
        length = length.max(u.norm());
        for scale in [0.75, 1.0, 1.25] {
            out.push(u * scale);
        }
    }
    // The step widths are rough (noise, neighbouring cells within reach): a coarse search
    // over directions at the estimated length as well.
    if length >= MIN_MOTION {
        for i in 0..8 {
            let angle = f64::from(i) * std::f64::consts::PI / 8.0;
            let dir = Vector2::new(angle.cos(), angle.sin());
            for scale in [0.8, 1.1] {
                out.push(dir * length * scale);
            }
        }
    }
    out
}

/// Cell levels of the grid of `family` under `corners` (taken as NW, NE, SE, SW) solved for
/// the motion `u`, with the mean squared misfit of the samples; `None` when the frame or the
/// system cannot be built. Levels cover cells `-k..w + k` by `-k..h + k`.
struct Solved {
    levels: Vec<f64>,
    k: i32,
    misfit: f64,
}

fn solve_levels(
    image: &GrayView<'_>,
    frame: &CrossRatioFrame,
    family: MarkerFamily,
    u: Vector2<f64>,
    k: i32,
) -> Option<Solved> {
    let (wc, hc) = (family.width_cells() as i32, family.height_cells() as i32);
    let (gw, gh) = (wc + 2 * k, hc + 2 * k);
    let n = (gw * gh) as usize;
    let mut ata = DMatrix::<f64>::zeros(n, n);
    let mut atb = DVector::<f64>::zeros(n);
    let mut rows: Vec<(Vec<(usize, f64)>, f64)> = Vec::new();
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
                    let mut w: Vec<(usize, f64)> = Vec::with_capacity(4);
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
                        let idx = (iy * gw + ix) as usize;
                        match w.iter_mut().find(|(c, _)| *c == idx) {
                            Some(e) => e.1 += 1.0 / SEG as f64,
                            None => w.push((idx, 1.0 / SEG as f64)),
                        }
                    }
                    if inside {
                        rows.push((w, obs));
                    }
                }
            }
        }
    }
    if rows.len() < n / 2 {
        return None;
    }
    let mean = rows.iter().map(|r| r.1).sum::<f64>() / rows.len() as f64;
    for (w, obs) in &rows {
        for &(i, wi) in w {
            atb[i] += wi * (obs - mean);
            for &(j, wj) in w {
                ata[(i, j)] += wi * wj;
            }
        }
    }
    // A light ridge towards the mean keeps cells few samples see (the outer ring) defined.
    let ridge = 0.02 * 9.0;
    for i in 0..n {
        ata[(i, i)] += ridge;
    }
    let x = ata.cholesky()?.solve(&atb);
    let mut misfit = 0.0;
    for (w, obs) in &rows {
        let m: f64 = w.iter().map(|&(i, wi)| wi * x[i]).sum();
        misfit += (m - (obs - mean)).powi(2);
    }
    let levels = x.iter().map(|v| v + mean).collect();
    Some(Solved {
        levels,
        k,
        misfit: misfit / rows.len() as f64,
    })
}

/// The reading of solved levels, as [`crate::decode::read_cells_with`] reads sampled ones.
fn reading(
    solved: &Solved,
    family: MarkerFamily,
    white: WhiteReference,
    params: &DecodeParams,
) -> Option<CellReading> {
    let (wc, hc) = (family.width_cells() as i32, family.height_cells() as i32);
    let gw = wc + 2 * solved.k;
    let at = |x: i32, y: i32| solved.levels[((y + solved.k) * gw + x + solved.k) as usize];
    let mut border = Vec::new();
    let mut quiet = Vec::new();
    for y in -1..=hc {
        for x in -1..=wc {
            let ring = x == -1 || y == -1 || x == wc || y == hc;
            let edge = x == 0 || y == 0 || x == wc - 1 || y == hc - 1;
            if ring {
                quiet.push(at(x, y));
            } else if edge {
                border.push(at(x, y));
            }
        }
    }
    let (m, n) = (family.rows() as i32, family.cols() as i32);
    let mut data = [0.0f64; 64];
    for r in 0..m {
        for c in 0..n {
            data[(r * n + c) as usize] = at(c + 1, r + 1);
        }
    }
    reading_from_levels(
        &mut border,
        &mut quiet,
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
) -> Option<Decoded> {
    let us = motions(image, corners);
    if us.is_empty() {
        return None;
    }
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
            let solved = us
                .iter()
                .filter_map(|u| {
                    let k = (1.0 + (0.5 * u.norm() / pitch.max(1.0)).ceil()).min(4.0) as i32;
                    solve_levels(image, &frame, family, *u, k)
                })
                .min_by(|a, b| a.misfit.total_cmp(&b.misfit));
            let Some(solved) = solved else {
                continue;
            };
            let Some(r) = reading(&solved, family, white, &exact) else {
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
