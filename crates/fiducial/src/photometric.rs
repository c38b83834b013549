//! Corners fitted to the image of the decoded marker (issue #30: the `far` bias).
//!
//! The edge rules of [`crate::refine`] and [`crate::pattern`] locate each side from profiles
//! across it, against levels read near it. On a small marker with a one-cell quiet zone
//! that fails in one known way: whatever lies beyond the quiet zone (the ground, the
//! robot's body, the next face of a rig) is blurred into it, the white level reads low, and
//! every edge moves inwards. Under a 1 px blur, markers of 2-3 px cells seen 3.3-3.8 m away
//! read 0.07-0.12 px small per corner, which puts `l12` 6-16 mm too far.
//!
//! This step models the whole marker instead of its edges. Once a marker is decoded its
//! cells are known; so is its one-cell white quiet zone. Beyond that lies an unknown
//! surround, one level per side. The grey level at every pixel of the marker and its quiet
//! zone is modelled as that picture, mapped into the image by the homography of
//! the four corners and blurred by a Gaussian of `sigma` pixels:
//!
//! `g(p) = lo + c W(p) (1 + gx x(p) + gy y(p)) + sum_k s_k S_k(p)`
//!
//! where `W` is the blurred whiteness of the pattern and its quiet zone and `S_k` the
//! blurred share of side `k`'s surround. The blur is applied separably along the marker's
//! axes, with each axis's width in cells taken from the homography's local scale at the
//! pixel (exact for a straight edge, close near corners of moderate perspective). The levels
//! (`lo`, `c`, the light gradient `gx, gy` and the four surrounds) enter linearly and are
//! solved by least squares for each geometry; the eight corner coordinates and `ln sigma`
//! are fitted by Levenberg-Marquardt on the remaining misfit (variable projection). Each
//! step is the Gauss-Newton step on geometry and levels together, kept for the geometry:
//! the Jacobian projected off what the levels absorb (the Schur complement of the levels'
//! block). Without the projection the fit converged only linearly and left the far scene's
//! `l12` 0.2 mm further out; with it a fit stops after 3-5 iterations, when the misfit falls
//! by less than a thousandth, about 0.5-2 ms on a 30-50 px tag. The surround's blur
//! into the quiet zone is what the edge rules miss; the fit needs no pixel beyond it. The
//! plain or pattern corners start it; the result is kept only if it moves no corner more
//! than a cell.

use crate::cross_ratio::square_to_quad;
use crate::image::{Corners, GrayView};
use crate::pattern::{Cells, MAX_CELLS, interpolate, phi, tabulate};
use nalgebra::{Matrix3, Point2, SMatrix, SVector, Vector2, Vector3};

/// Linear levels: `lo`, `c`, `c gx`, `c gy`, four surrounds.
const LIN: usize = 8;
/// Nonlinear parameters: eight corner coordinates and `ln sigma`.
const NL: usize = 9;
/// Boundaries along one axis of the extended grid: surround | quiet | cells | quiet | surround.
const MAX_BOUNDS: usize = MAX_CELLS + 3;
/// The quiet zone's width in cells: the fitted pixels' margin around the marker (none
/// beyond it: what lies there is not modelled, only its blur into the quiet zone).
const QUIET: f64 = 1.0;
/// Most Levenberg-Marquardt iterations.
const MAX_ITER: usize = 6;

/// Stop when no corner moves more than this (pixels).
const STOP_PX: f64 = 4e-3;
/// Stop when an iteration lowers the misfit by less than this share of it.
const STOP_GAIN: f64 = 1e-3;
/// Forward-difference step (pixels for corners, for `ln sigma` too).
const STEP: f64 = 1e-4;
/// Blur range accepted (pixels).
const SIGMA_RANGE: [f64; 2] = [0.25, 4.0];
/// Least contrast (grey levels) of a marker the model is fitted to (the edge rule's
/// `RefineConfig::min_edge_contrast` default).
const MIN_CONTRAST: f64 = 10.0;
/// Most pixels fitted (a marker of 8 x 8 cells at 8 px a cell, with its quiet zone).
const MAX_PIXELS: usize = 12_000;

/// Scratch of the photometric fit (owned by the detector's decode scratch).
#[derive(Debug, Clone, Default)]
pub(crate) struct PhotometricFit {
    /// Pixel centre and grey level of each fitted pixel.
    px: Vec<[f64; 3]>,
    /// Design rows of the linear levels at the current geometry, and at a trial.
    rows: Vec<[f64; LIN]>,
    /// Residuals at the current parameters and at a trial.
    r: Vec<f64>,
    trial: Vec<f64>,
    /// Levenberg-Marquardt iterations the last fit took.
    iterations: usize,
}

/// The linear levels: `lo`, `c`, `c gx`, `c gy`, the four surrounds (minus `lo`).
type Levels = SVector<f64, LIN>;

/// The homography from marker coordinates (cells, the border's outer corners at `(0, 0)`,
/// `(cols, 0)`, `(cols, rows)`, `(0, rows)`) to the image, and its inverse.
fn homographies(c: &[f64; 8], cols: f64, rows: f64) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    let p = [
        Vector2::new(c[0], c[1]),
        Vector2::new(c[2], c[3]),
        Vector2::new(c[4], c[5]),
        Vector2::new(c[6], c[7]),
    ];
    let h = square_to_quad(p)?;
    let m = Matrix3::new(
        h[0] / cols,
        h[1] / rows,
        h[2],
        h[3] / cols,
        h[4] / rows,
        h[5],
        h[6] / cols,
        h[7] / rows,
        1.0,
    );
    let inv = m.try_inverse()?;
    Some((m, inv))
}

/// The extended grid: surround, quiet zone, the marker's cells, quiet zone, surround.
struct Grid {
    cols: usize,
    rows: usize,
    /// Each cell's share of the white level and of the four surrounds (0 top, 1 right, 2
    /// bottom, 3 left): 1 for a white cell of the marker or its quiet zone, nothing for a
    /// black one, 1 for a side's surround and a half each for a corner of the surround
    /// shared by two sides. The model sums them without a branch per cell (a branch on the
    /// cell's kind mispredicted on the random pattern and cost half the fit's time).
    share: [[[f64; 5]; MAX_BOUNDS + 1]; MAX_BOUNDS + 1],
}

/// The surround side (`before` or `after`) of index `k` of an extended axis over `n` cells,
/// or `None` inside the surround.
fn ring_side(k: usize, n: usize, before: usize, after: usize) -> Option<usize> {
    if k == 0 {
        Some(before)
    } else if k == n + 3 {
        Some(after)
    } else {
        None
    }
}

impl Grid {
    fn new(cells: &Cells) -> Self {
        let (cn, rn) = (cells.cols, cells.rows);
        const WHITE: [f64; 5] = [1.0, 0.0, 0.0, 0.0, 0.0];
        let mut share = [[WHITE; MAX_BOUNDS + 1]; MAX_BOUNDS + 1];
        for (j, row) in share.iter_mut().enumerate().take(rn + 4) {
            for (i, sh) in row.iter_mut().enumerate().take(cn + 4) {
                *sh = [0.0; 5];
                match (ring_side(j, rn, 0, 2), ring_side(i, cn, 3, 1)) {
                    (Some(a), Some(b)) => {
                        sh[1 + a] = 0.5;
                        sh[1 + b] = 0.5;
                    }
                    (Some(a), None) | (None, Some(a)) => sh[1 + a] = 1.0,
                    (None, None) => {
                        if j == 1
                            || j == rn + 2
                            || i == 1
                            || i == cn + 2
                            || !cells.black[j - 2][i - 2]
                        {
                            sh[0] = 1.0;
                        }
                    }
                }
            }
        }
        Self {
            cols: cn,
            rows: rn,
            share,
        }
    }
}

/// Blur weights of the extended grid's intervals along one axis, and their derivatives
/// with respect to the position and the blur width. Only intervals `first..=last` can be
/// non-zero: boundaries more than [`TAIL`] blur widths away are taken as fully crossed or
/// not reached.
struct Axis {
    w: [f64; MAX_BOUNDS + 1],
    dx: [f64; MAX_BOUNDS + 1],
    ds: [f64; MAX_BOUNDS + 1],
    first: usize,
    last: usize,
}

/// Blur widths beyond which a boundary counts as crossed (the normal tail there is 2e-4,
/// a twentieth of a grey level on a marker of 200 levels' contrast).
const TAIL: f64 = 3.5;

/// Range and resolution of [`pdf`]'s table.
const PDF_RANGE: f64 = 8.0;
const PDF_STEPS: usize = 2048;

/// The standard normal density, interpolated in a table (relative error under 1e-5 where
/// it matters; it enters only the Jacobian, never the misfit). Zero beyond the range.
#[inline]
fn pdf(z: f64) -> f64 {
    static TABLE: std::sync::OnceLock<[f64; PDF_STEPS + 1]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        tabulate(PDF_RANGE, |z| {
            (-0.5 * z * z).exp() * 0.398_942_280_401_432_7
        })
    });
    interpolate(table, PDF_RANGE, z).unwrap_or(0.0)
}

impl Axis {
    fn new() -> Self {
        Self {
            w: [0.0; MAX_BOUNDS + 1],
            dx: [0.0; MAX_BOUNDS + 1],
            ds: [0.0; MAX_BOUNDS + 1],
            first: 0,
            last: 0,
        }
    }

    /// The weights at `x` (cells) for blur `s` (cells) over `n` cells; with `deriv` their
    /// derivatives too. Boundary `k` lies at `k - 1`; interval `k` ends at boundary `k`.
    #[inline]
    fn set(&mut self, x: f64, s: f64, n: usize, deriv: bool) {
        let inv = 1.0 / s;
        let m = (n + 3) as f64;
        // Boundaries kmin..kmax lie within TAIL widths of x. Rounded by casts: `ceil` and
        // `floor` are library calls on the baseline x86-64 target, a third of this
        // function's time.
        let lo = (x - TAIL * s + 1.0).clamp(0.0, m);
        let kmin = lo as usize + usize::from((lo as usize as f64) < lo);
        let kmax = (x + TAIL * s + 2.0).clamp(kmin as f64, m) as usize;
        let (mut prev, mut prev_pdf, mut prev_zpdf) = (0.0, 0.0, 0.0);
        for k in kmin..kmax {
            let z = (k as f64 - 1.0 - x) * inv;
            let cdf = phi(z);
            self.w[k] = cdf - prev;
            prev = cdf;
            if deriv {
                let d = pdf(z);
                self.dx[k] = -(d - prev_pdf) * inv;
                self.ds[k] = -(z * d - prev_zpdf) * inv;
                prev_pdf = d;
                prev_zpdf = z * d;
            }
        }
        self.w[kmax] = 1.0 - prev;
        if deriv {
            self.dx[kmax] = prev_pdf * inv;
            self.ds[kmax] = prev_zpdf * inv;
        }
        self.first = kmin;
        self.last = kmax;
    }
}

/// A pixel's place in the marker: its marker coordinates, the inverse map's Jacobian
/// `d(x, y) / d(u, v)` and the blur widths along the marker's axes (cells).
struct Place {
    x: f64,
    y: f64,
    jac: [[f64; 2]; 2],
    sx: f64,
    sy: f64,
}

#[inline]
fn place(g: &Matrix3<f64>, u: f64, v: f64, sigma: f64) -> Option<Place> {
    let w = g[(2, 0)] * u + g[(2, 1)] * v + g[(2, 2)];
    if w.abs().partial_cmp(&1e-12) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let x = (g[(0, 0)] * u + g[(0, 1)] * v + g[(0, 2)]) / w;
    let y = (g[(1, 0)] * u + g[(1, 1)] * v + g[(1, 2)]) / w;
    let jac = [
        [
            (g[(0, 0)] - x * g[(2, 0)]) / w,
            (g[(0, 1)] - x * g[(2, 1)]) / w,
        ],
        [
            (g[(1, 0)] - y * g[(2, 0)]) / w,
            (g[(1, 1)] - y * g[(2, 1)]) / w,
        ],
    ];
    let sx = sigma * (jac[0][0] * jac[0][0] + jac[0][1] * jac[0][1]).sqrt();
    let sy = sigma * (jac[1][0] * jac[1][0] + jac[1][1] * jac[1][1]).sqrt();
    (sx > 0.0 && sy > 0.0 && x.is_finite() && y.is_finite()).then_some(Place { x, y, jac, sx, sy })
}

/// Adds `a[k] b` to row `k` of `g`: one pixel's share of the cross products of `a` and `b`.
#[inline]
fn add_outer<const N: usize, const M: usize>(g: &mut [[f64; M]; N], a: &[f64; N], b: &[f64; M]) {
    for (gk, &ak) in g.iter_mut().zip(a) {
        for (x, &bl) in gk.iter_mut().zip(b) {
            *x += ak * bl;
        }
    }
}

/// The levels solved for one geometry.
struct Solved {
    /// Sum of squared residuals.
    cost: f64,
    levels: Levels,
    /// `A^T A` of the levels' design, with its ridge.
    ata: SMatrix<f64, LIN, LIN>,
}

impl PhotometricFit {
    /// Fits the corners (the marker's own NW, NE, SE, SW) of a decoded marker with cells
    /// `cells` to the image, starting from `corners` and a blur of `sigma0` px. `None` when
    /// the model cannot be fitted or ends more than `limit` px from the start (the caller
    /// keeps its corners).
    pub(crate) fn fit(
        &mut self,
        img: &GrayView<'_>,
        corners: &Corners,
        cells: &Cells,
        sigma0: f64,
        limit: f64,
    ) -> Option<Corners> {
        let grid = Grid::new(cells);
        let mut theta = [0.0; NL];
        for (i, p) in corners.iter().enumerate() {
            theta[2 * i] = p.x;
            theta[2 * i + 1] = p.y;
        }
        theta[8] = sigma0.clamp(SIGMA_RANGE[0], SIGMA_RANGE[1]).ln();
        self.select_pixels(img, &theta, &grid)?;
        let n = self.px.len();
        self.r.resize(n, 0.0);
        self.trial.resize(n, 0.0);
        self.rows.resize(n, [0.0; LIN]);
        self.solve(&grid, &mut theta)?;
        let mut fitted = [Point2::origin(); 4];
        for (i, p) in fitted.iter_mut().enumerate() {
            *p = Point2::new(theta[2 * i], theta[2 * i + 1]);
        }
        for (c, k) in fitted.iter().zip(corners) {
            let moved = (k.x - c.x).hypot(k.y - c.y);
            if moved.is_nan() || moved > limit {
                return None;
            }
        }
        let sigma = theta[8].exp();
        (SIGMA_RANGE[0]..=SIGMA_RANGE[1])
            .contains(&sigma)
            .then_some(fitted)
    }

    /// Gauss-Newton with Levenberg-Marquardt damping on the corners and `ln sigma`, the
    /// Jacobian projected off the levels (see the module documentation).
    fn solve(&mut self, grid: &Grid, theta: &mut [f64; NL]) -> Option<()> {
        let mut r = std::mem::take(&mut self.r);
        let mut trial = std::mem::take(&mut self.trial);
        let out = self.iterate(grid, theta, &mut r, &mut trial);
        self.r = r;
        self.trial = trial;
        out
    }

    fn iterate(
        &mut self,
        grid: &Grid,
        theta: &mut [f64; NL],
        r: &mut [f64],
        trial: &mut [f64],
    ) -> Option<()> {
        let mut now = self.residuals(grid, theta, r)?;
        let mut lambda = 1e-3;
        self.iterations = 0;
        for _ in 0..MAX_ITER {
            self.iterations += 1;
            let (jtj, jtr) = self.normal_equations(grid, theta, &now, r)?;
            let mut accepted = false;
            let mut step_px = 0.0;
            let mut gain = 0.0;
            for _ in 0..6 {
                let mut a = jtj;
                for d in 0..NL {
                    a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
                }
                let delta = a.cholesky()?.solve(&jtr);
                let mut t = *theta;
                for (v, d) in t.iter_mut().zip(delta.iter()) {
                    *v += d;
                }
                if !(SIGMA_RANGE[0].ln() - 1.0..=SIGMA_RANGE[1].ln() + 1.0).contains(&t[8]) {
                    lambda *= 4.0;
                    continue;
                }
                if let Some(next) = self.residuals(grid, &t, trial)
                    && next.cost < now.cost
                {
                    step_px = delta.iter().take(8).fold(0.0f64, |m, d| m.max(d.abs()));
                    gain = (now.cost - next.cost) / now.cost;
                    *theta = t;
                    now = next;
                    r.copy_from_slice(trial);
                    lambda = (lambda / 3.0).max(1e-7);
                    accepted = true;
                    break;
                }
                lambda *= 4.0;
            }
            if !accepted || step_px < STOP_PX || gain < STOP_GAIN {
                break;
            }
        }
        now.cost.is_finite().then_some(())
    }

    /// Chooses the pixels fitted: centres on the marker or its quiet zone.
    fn select_pixels(&mut self, img: &GrayView<'_>, theta: &[f64; NL], grid: &Grid) -> Option<()> {
        let (cols, rows) = (grid.cols as f64, grid.rows as f64);
        let c: [f64; 8] = theta[..8].try_into().ok()?;
        let (h, g) = homographies(&c, cols, rows)?;
        let ext = QUIET;
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for (mx, my) in [
            (-ext, -ext),
            (cols + ext, -ext),
            (cols + ext, rows + ext),
            (-ext, rows + ext),
        ] {
            let p = h * Vector3::new(mx, my, 1.0);
            if p.z.partial_cmp(&1e-9) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            let (x, y) = (p.x / p.z, p.y / p.z);
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
        let (w, hgt) = (img.width() as f64, img.height() as f64);
        // Every pixel of the fitted area must be in the frame (NaN fails too).
        if !(x0 >= 0.0 && y0 >= 0.0 && x1 <= w - 1.0 && y1 <= hgt - 1.0) {
            return None;
        }
        if (x1 - x0 + 1.0) * (y1 - y0 + 1.0) > 2.0 * MAX_PIXELS as f64 {
            return None;
        }
        self.px.clear();
        for yi in y0.ceil() as usize..=y1.floor() as usize {
            let row = img.row(yi);
            let (xa, xb) = (x0.ceil() as usize, x1.floor() as usize);
            for (xi, &grey) in row.iter().enumerate().take(xb + 1).skip(xa) {
                let (u, v) = (xi as f64, yi as f64);
                let q = g * Vector3::new(u, v, 1.0);
                let (mx, my) = (q.x / q.z, q.y / q.z);
                if (-ext..=cols + ext).contains(&mx) && (-ext..=rows + ext).contains(&my) {
                    self.px.push([u, v, f64::from(grey)]);
                }
            }
        }
        (self.px.len() <= MAX_PIXELS && self.px.len() > LIN * 8).then_some(())
    }

    /// Fills the design rows at `theta`, solves the linear levels and writes the residuals.
    fn residuals(&mut self, grid: &Grid, theta: &[f64; NL], out: &mut [f64]) -> Option<Solved> {
        let (cols, rows) = (grid.cols as f64, grid.rows as f64);
        let c: [f64; 8] = theta[..8].try_into().ok()?;
        let (_, g) = homographies(&c, cols, rows)?;
        let sigma = theta[8].exp();
        let (mut ax, mut by) = (Axis::new(), Axis::new());
        // `A^T [A | b]`, row by row.
        let mut gram = [[0.0; LIN + 1]; LIN];
        for (p, row) in self.px.iter().zip(self.rows.iter_mut()) {
            let pl = place(&g, p[0], p[1], sigma)?;
            ax.set(pl.x, pl.sx, grid.cols, false);
            by.set(pl.y, pl.sy, grid.rows, false);
            let mut acc = [0.0; 5];
            for j in by.first..=by.last {
                let b = by.w[j];
                for i in ax.first..=ax.last {
                    let wgt = ax.w[i] * b;
                    for (a, sh) in acc.iter_mut().zip(&grid.share[j][i]) {
                        *a += wgt * sh;
                    }
                }
            }
            let [white, sur @ ..] = acc;
            let (dx, dy) = (pl.x / cols - 0.5, pl.y / rows - 0.5);
            *row = [
                1.0,
                white,
                white * dx,
                white * dy,
                sur[0],
                sur[1],
                sur[2],
                sur[3],
            ];
            let mut with_grey = [p[2]; LIN + 1];
            with_grey[..LIN].copy_from_slice(row);
            add_outer(&mut gram, row, &with_grey);
        }
        let mut ata = SMatrix::<f64, LIN, LIN>::from_fn(|i, j| gram[i][j]);
        let atb = Levels::from_fn(|i, _| gram[i][LIN]);
        // A surround no pixel sees is held near the dark level by a light ridge.
        let scale = ata[(0, 0)].max(1.0);
        for d in 0..LIN {
            ata[(d, d)] += 1e-9 * scale;
        }
        let levels = ata.cholesky()?.solve(&atb);
        if levels[1].partial_cmp(&MIN_CONTRAST) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let mut sse = 0.0;
        for ((p, row), o) in self.px.iter().zip(&self.rows).zip(out.iter_mut()) {
            let m: f64 = row.iter().zip(levels.iter()).map(|(a, l)| a * l).sum();
            *o = p[2] - m;
            sse += *o * *o;
        }
        sse.is_finite().then_some(Solved {
            cost: sse,
            levels,
            ata,
        })
    }

    /// `J^T J` and `-J^T r` of the model at `theta` with the levels `now` held, `r` its
    /// residuals, `J` projected off what the levels absorb.
    fn normal_equations(
        &self,
        grid: &Grid,
        theta: &[f64; NL],
        now: &Solved,
        r: &[f64],
    ) -> Option<(SMatrix<f64, NL, NL>, SVector<f64, NL>)> {
        let (cols, rows) = (grid.cols as f64, grid.rows as f64);
        let c: [f64; 8] = theta[..8].try_into().ok()?;
        let (h, g) = homographies(&c, cols, rows)?;
        // The forward map's derivative along each corner coordinate (a forward difference):
        // how a fixed marker point's image moves with the corners.
        let mut moved = [Matrix3::zeros(); 8];
        for (k, m) in moved.iter_mut().enumerate() {
            let mut ck = c;
            ck[k] += STEP;
            *m = (homographies(&ck, cols, rows)?.0 - h) / STEP;
        }
        let sigma = theta[8].exp();
        let (mut ax, mut by) = (Axis::new(), Axis::new());
        let levels = &now.levels;
        // `J^T [J | A | r]` with `A` the levels' design (rows filled at `theta` by
        // `residuals`): the step is projected off what the levels absorb.
        let mut gram = [[0.0; NL + LIN + 1]; NL];
        // Each cell's white share and surround level.
        let mut cell = [[[0.0; 2]; MAX_BOUNDS + 1]; MAX_BOUNDS + 1];
        for (crow, srow) in cell.iter_mut().zip(&grid.share) {
            for (c, sh) in crow.iter_mut().zip(srow) {
                *c = [sh[0], (0..4).map(|k| sh[1 + k] * levels[4 + k]).sum()];
            }
        }
        for ((p, &e), arow) in self.px.iter().zip(r).zip(&self.rows) {
            let pl = place(&g, p[0], p[1], sigma)?;
            ax.set(pl.x, pl.sx, grid.cols, true);
            by.set(pl.y, pl.sy, grid.rows, true);
            let (dx, dy) = (pl.x / cols - 0.5, pl.y / rows - 0.5);
            let c_eff = levels[1] + levels[2] * dx + levels[3] * dy;
            // Derivatives of the model (levels held) along x, y, sx, sy, and the whiteness.
            let (mut mx, mut my, mut msx, mut msy, mut white) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for (crow, j) in cell[by.first..=by.last].iter().zip(by.first..) {
                let (b, bd, bs) = (by.w[j], by.dx[j], by.ds[j]);
                for (&[cw, lsur], i) in crow[ax.first..=ax.last].iter().zip(ax.first..) {
                    let (a, ad, as_) = (ax.w[i], ax.dx[i], ax.ds[i]);
                    white += cw * a * b;
                    let level = cw * c_eff + lsur;
                    mx += level * ad * b;
                    my += level * a * bd;
                    msx += level * as_ * b;
                    msy += level * a * bs;
                }
            }
            // The light gradient moves with the point too.
            mx += levels[2] / cols * white;
            my += levels[3] / rows * white;
            let mut jrow = [0.0; NL];
            let at = Vector3::new(pl.x, pl.y, 1.0);
            let here = h * at;
            let inv = 1.0 / here.z;
            let (u0, v0) = (here.x * inv, here.y * inv);
            for (k, m) in moved.iter().enumerate() {
                let q = m * at;
                let (du, dv) = ((q.x - u0 * q.z) * inv, (q.y - v0 * q.z) * inv);
                // The marker point seen at this pixel moves by -d(x, y)/d(u, v) (du, dv).
                let dxk = -(pl.jac[0][0] * du + pl.jac[0][1] * dv);
                let dyk = -(pl.jac[1][0] * du + pl.jac[1][1] * dv);
                jrow[k] = mx * dxk + my * dyk;
            }
            jrow[8] = msx * pl.sx + msy * pl.sy;
            // Residual = grey - model, so its Jacobian is -jrow; the step solves
            // (J^T J) d = -J^T r = jrow^T r.
            let mut b = [e; NL + LIN + 1];
            b[..NL].copy_from_slice(&jrow);
            b[NL..NL + LIN].copy_from_slice(arow);
            add_outer(&mut gram, &jrow, &b);
        }
        let jtj = SMatrix::<f64, NL, NL>::from_fn(|i, j| gram[i][j]);
        let jta = SMatrix::<f64, NL, LIN>::from_fn(|i, j| gram[i][NL + j]);
        let jtr = SVector::<f64, NL>::from_fn(|i, _| gram[i][NL + LIN]);
        // The Gauss-Newton step on corners, blur and levels together, kept for the
        // corners and blur (the Schur complement; `A^T r = 0` at the solved levels).
        let absorbed = jta * now.ata.cholesky()?.solve(&jta.transpose());
        Some((jtj - absorbed, jtr))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::Dictionary;

    /// Renders a marker of `cells` whose border's outer corners are `corners`, with a one-cell
    /// white (200) quiet zone and `surround` beyond, ink 20, 8 x 8 samples per pixel, then a
    /// Gaussian blur of `sigma` px.
    fn render(
        w: usize,
        h: usize,
        corners: &Corners,
        cells: &Cells,
        surround: f64,
        sigma: f64,
    ) -> Vec<u8> {
        let c: [f64; 8] = [
            corners[0].x,
            corners[0].y,
            corners[1].x,
            corners[1].y,
            corners[2].x,
            corners[2].y,
            corners[3].x,
            corners[3].y,
        ];
        let (cols, rows) = (cells.cols as f64, cells.rows as f64);
        let (_, g) = homographies(&c, cols, rows).unwrap();
        let mut img = vec![0.0f64; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let u = x as f64 - 0.5 + (sx as f64 + 0.5) / 8.0;
                        let v = y as f64 - 0.5 + (sy as f64 + 0.5) / 8.0;
                        let q = g * nalgebra::Vector3::new(u, v, 1.0);
                        let (mx, my) = (q.x / q.z, q.y / q.z);
                        let level =
                            if mx < -1.0 || my < -1.0 || mx >= cols + 1.0 || my >= rows + 1.0 {
                                surround
                            } else if mx < 0.0 || my < 0.0 || mx >= cols || my >= rows {
                                200.0
                            } else if cells.black[my as usize][mx as usize] {
                                20.0
                            } else {
                                200.0
                            };
                        acc += level;
                    }
                }
                img[y * w + x] = acc / 64.0;
            }
        }
        // Separable Gaussian blur.
        let r = (4.0 * sigma).ceil() as i64;
        let k: Vec<f64> = (-r..=r)
            .map(|d| (-(d * d) as f64 / (2.0 * sigma * sigma)).exp())
            .collect();
        let ks: f64 = k.iter().sum();
        let mut tmp = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut a = 0.0;
                for (i, kv) in k.iter().enumerate() {
                    let xx = (x as i64 + i as i64 - r).clamp(0, w as i64 - 1) as usize;
                    a += kv * img[y * w + xx];
                }
                tmp[y * w + x] = a / ks;
            }
        }
        let mut out = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut a = 0.0;
                for (i, kv) in k.iter().enumerate() {
                    let yy = (y as i64 + i as i64 - r).clamp(0, h as i64 - 1) as usize;
                    a += kv * tmp[yy * w + x];
                }
                out[y * w + x] = (a / ks).round().clamp(0.0, 255.0) as u8;
            }
        }
        out
    }

    fn paper_cells() -> Cells {
        let d = Dictionary::paper();
        Cells::new(d.family(), d.code(3).unwrap()).unwrap()
    }

    fn err(a: &Corners, b: &Corners) -> f64 {
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn small_marker_on_a_dark_surround_is_fitted_to_its_true_corners() {
        let cells = paper_cells();
        let truth: Corners = [
            Point2::new(30.3, 28.7),
            Point2::new(50.1, 29.6),
            Point2::new(49.4, 51.2),
            Point2::new(29.8, 50.4),
        ];
        let moves = [[0.15, -0.1], [-0.1, 0.2], [0.12, 0.05], [-0.2, -0.12]];
        let (out, _) = fit_rendered(&cells, &truth, 40.0, 1.0, moves);
        let e = err(&out, &truth);
        assert!(e < 0.03, "corner error {e} px");
    }

    /// Renders `truth` on an 80 x 80 frame (`render`'s `surround` and `sigma`) and fits it
    /// from the corners moved by `moves`: the fitted corners and the iterations taken.
    fn fit_rendered(
        cells: &Cells,
        truth: &Corners,
        surround: f64,
        sigma: f64,
        moves: [[f64; 2]; 4],
    ) -> (Corners, usize) {
        let img = render(80, 80, truth, cells, surround, sigma);
        let view = GrayView::new(&img, 80, 80).unwrap();
        let mut start = *truth;
        for (p, m) in start.iter_mut().zip(moves) {
            p.x += m[0];
            p.y += m[1];
        }
        let mut fit = PhotometricFit::default();
        let out = fit.fit(&view, &start, cells, 1.0, 1.0).expect("fits");
        (out, fit.iterations)
    }

    /// The projected step converges in a few iterations where the unprojected one took
    /// every one it was allowed (regression, 2026-12-07).
    #[test]
    fn the_fit_converges_well_within_its_iteration_limit() {
        let cells = paper_cells();
        let mut worst = 0;
        for (k, shift) in [0.0, 0.3, 0.6, 0.9].into_iter().enumerate() {
            let truth: Corners = [
                Point2::new(30.3 + shift, 28.7),
                Point2::new(48.1 + shift, 30.6 + shift),
                Point2::new(47.4, 47.2 + shift),
                Point2::new(29.8, 46.4),
            ];
            let moves = [[0.2, -0.15], [-0.15, 0.2], [0.1, 0.1], [-0.2, -0.1]];
            let surround = 40.0 + 30.0 * k as f64;
            let (out, iterations) = fit_rendered(&cells, &truth, surround, 1.2, moves);
            assert!(err(&out, &truth) < 0.03, "scene {k}: {}", err(&out, &truth));
            worst = worst.max(iterations);
        }
        assert!(worst <= 4, "took {worst} of {MAX_ITER} iterations");
    }

    #[test]
    fn a_flat_image_or_corners_off_the_frame_are_refused_without_panicking() {
        let cells = paper_cells();
        let flat = vec![128u8; 80 * 80];
        let view = GrayView::new(&flat, 80, 80).unwrap();
        let c: Corners = [
            Point2::new(30.0, 30.0),
            Point2::new(50.0, 30.0),
            Point2::new(50.0, 50.0),
            Point2::new(30.0, 50.0),
        ];
        let mut fit = PhotometricFit::default();
        assert!(fit.fit(&view, &c, &cells, 1.0, 3.0).is_none());
        let mut off = c;
        off[1].x = 95.0;
        assert!(fit.fit(&view, &off, &cells, 1.0, 3.0).is_none());
        let mut nan = c;
        nan[2].y = f64::NAN;
        assert!(fit.fit(&view, &nan, &cells, 1.0, 3.0).is_none());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        /// Any start near a rendered marker gives corners within the limit of the start, or
        /// none; never NaN.
        #[test]
        fn output_is_finite_and_within_the_limit(
            dx in proptest::array::uniform8(-0.6f64..0.6),
            side in 14.0f64..30.0,
            surround in 0.0f64..220.0,
        ) {
            let cells = paper_cells();
            let truth: Corners = [
                Point2::new(20.0, 20.0),
                Point2::new(20.0 + side, 21.0),
                Point2::new(19.5 + side, 20.0 + side),
                Point2::new(20.5, 19.0 + side),
            ];
            let img = render(64, 64, &truth, &cells, surround, 1.0);
            let view = GrayView::new(&img, 64, 64).unwrap();
            let mut start = truth;
            for (i, p) in start.iter_mut().enumerate() {
                p.x += dx[2 * i];
                p.y += dx[2 * i + 1];
            }
            let mut fit = PhotometricFit::default();
            if let Some(out) = fit.fit(&view, &start, &cells, 1.0, 1.0) {
                for (p, q) in out.iter().zip(&start) {
                    proptest::prop_assert!(p.x.is_finite() && p.y.is_finite());
                    proptest::prop_assert!((p - q).norm() <= 1.0);
                }
            }
        }
    }
}
