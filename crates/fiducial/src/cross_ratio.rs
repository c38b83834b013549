//! Cell centres by cross ratio (spec 3.5, the paper's eqs. 8-19 re-derived).
//!
//! Given the image corners `q_NW, q_NE, q_SE, q_SW` of a planar rectangle, the image of the
//! point with normalised marker coordinates `(a, b)` (`a` to the right, `b` downward, the
//! rectangle being `[-1, 1]^2`) is built with lines and points in homogeneous coordinates:
//!
//! ```text
//! q_c = (q_NW x q_SE) x (q_SW x q_NE)        centre: the diagonals meet
//! v1  = (q_SE x q_SW) x (q_NE x q_NW)        vanishing point of top/bottom edges
//! v2  = (q_NE x q_SE) x (q_NW x q_SW)        vanishing point of left/right edges
//! q_W = (q_NW x q_SW) x (v1 x q_c),  q_E = (q_NE x q_SE) x (v1 x q_c)
//! q_N = (q_NW x q_NE) x (v2 x q_c),  q_S = (q_SW x q_SE) x (v2 x q_c)
//! ```
//!
//! On each edge the cross ratio fixes the image of `a` (or `b`): with
//! `rho = 2|a| / (1 + |a|)` and, on the top edge, `A = d(q_NW, q_N)`, `B = d(q_N, q_NE)`,
//! `D = d(q_NW, q_NE)`, the point lies at distance `t = A B rho / (D - B rho)` from `q_N`
//! towards `q_NE` when `a >= 0`, or `t = A B rho / (D - A rho)` towards `q_NW` when
//! `a < 0`. The image of `(a, b)` is `(q_aN x q_aS) x (q_bW x q_bE)`.
//!
//! The construction is exact for every projective view, and equals the homography fixed by
//! the four corners. The vanishing points may be at infinity (an affine view, where opposite
//! edges are parallel): they are ordinary homogeneous points with third coordinate 0 and
//! are never divided by it. Only points known to be finite (the edge mid-points, the final
//! point) are dehomogenised.
//!
//! To keep the arithmetic well conditioned whatever the pixel coordinates, the corners are
//! first moved to their centroid and scaled to unit size; results are mapped back.
//!
//! [`CrossRatioFrame::new`] runs the construction once (it is what checks the quad), and
//! [`CrossRatioFrame::map`] evaluates the homography it equals, written in closed form from
//! the four corners (Heckbert's square-to-quad mapping): one 3 x 3 product and a division
//! per point, instead of four edge points and three cross products. The decoder, the side
//! check and the motion-blurred reading map hundreds of points per marker, so this is a
//! tenth of a frame's detection time. [`CrossRatioFrame::map_by_construction`] keeps the
//! construction point by point, as the reference the tests compare against.

use nalgebra::{Point2, Vector2, Vector3};

use crate::error::FiducialError;
use crate::image::Corners;

/// One edge of the quad, prepared for the cross-ratio construction: its mid-point image
/// `q_mid` (the image of marker coordinate 0), unit directions towards the `+1` and `-1`
/// ends, and the distances `A` (from the `-1` end to `q_mid`), `B` (from `q_mid` to the
/// `+1` end) and `D = d(-1 end, +1 end)`.
#[derive(Debug, Clone, Copy)]
struct Edge {
    mid: Vector2<f64>,
    to_plus: Vector2<f64>,
    to_minus: Vector2<f64>,
    a: f64,
    b: f64,
    d: f64,
}

impl Edge {
    fn new(minus: Vector2<f64>, mid: Vector2<f64>, plus: Vector2<f64>) -> Option<Self> {
        let a = (mid - minus).norm();
        let b = (plus - mid).norm();
        let d = (plus - minus).norm();
        if !(a > 0.0 && b > 0.0 && d > 0.0 && a.is_finite() && b.is_finite()) {
            return None;
        }
        Some(Self {
            mid,
            to_plus: (plus - mid) / b,
            to_minus: (minus - mid) / a,
            a,
            b,
            d,
        })
    }

    /// The image of marker coordinate `s` on this edge, as a homogeneous point (w = 1);
    /// `None` beyond the horizon (only possible for `|s| > 1`).
    #[inline]
    fn point(&self, s: f64) -> Option<Vector3<f64>> {
        let rho = 2.0 * s.abs() / (1.0 + s.abs());
        let (den, dir) = if s >= 0.0 {
            (self.d - self.b * rho, self.to_plus)
        } else {
            (self.d - self.a * rho, self.to_minus)
        };
        if den.is_nan() || den <= 0.0 {
            return None;
        }
        let p = self.mid + dir * (self.a * self.b * rho / den);
        Some(Vector3::new(p.x, p.y, 1.0))
    }
}

/// A quad prepared for mapping normalised marker coordinates `(a, b)` to image points by
/// the cross-ratio construction. Building it costs a few dozen flops; each
/// [`CrossRatioFrame::map`] about a dozen more (the homography it equals). No allocation.
#[derive(Debug, Clone, Copy)]
pub struct CrossRatioFrame {
    top: Edge,
    bottom: Edge,
    left: Edge,
    right: Edge,
    origin: Vector2<f64>,
    scale: f64,
    /// The homography from the unit square (`s = (a + 1) / 2`, `t = (b + 1) / 2`) to the
    /// normalised corners: `x = (h0 s + h1 t + h2) / w`, `y = (h3 s + h4 t + h5) / w`,
    /// `w = h6 s + h7 t + 1`.
    h: [f64; 8],
}

/// A segment of marker coordinates and the frame that maps it
/// ([`CrossRatioFrame::segment`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct FrameSegment<'a> {
    frame: &'a CrossRatioFrame,
    /// Homogeneous image of the start, and the change to the end.
    start: [f64; 3],
    delta: [f64; 3],
}

impl FrameSegment<'_> {
    /// The image of the point a fraction `f` of the way along; `None` where
    /// [`CrossRatioFrame::map`] gives none (beyond the horizon, or not finite).
    #[inline]
    pub(crate) fn at(&self, f: f64) -> Option<Point2<f64>> {
        self.frame
            .image_of([0, 1, 2].map(|i| self.start[i] + f * self.delta[i]))
    }
}

/// Heckbert's closed-form homography taking the unit square's `(0, 0), (1, 0), (1, 1),
/// (0, 1)` to `p0..p3` (see [`CrossRatioFrame::h`]); `None` if it is degenerate.
pub(crate) fn square_to_quad(p: [Vector2<f64>; 4]) -> Option<[f64; 8]> {
    let (dx1, dy1) = (p[1].x - p[2].x, p[1].y - p[2].y);
    let (dx2, dy2) = (p[3].x - p[2].x, p[3].y - p[2].y);
    let (dx3, dy3) = (
        p[0].x - p[1].x + p[2].x - p[3].x,
        p[0].y - p[1].y + p[2].y - p[3].y,
    );
    let den = dx1 * dy2 - dx2 * dy1;
    if !(den.is_finite() && den != 0.0) {
        return None;
    }
    let g = (dx3 * dy2 - dx2 * dy3) / den;
    let h = (dx1 * dy3 - dx3 * dy1) / den;
    let out = [
        p[1].x - p[0].x + g * p[1].x,
        p[3].x - p[0].x + h * p[3].x,
        p[0].x,
        p[1].y - p[0].y + g * p[1].y,
        p[3].y - p[0].y + h * p[3].y,
        p[0].y,
        g,
        h,
    ];
    out.iter().all(|v| v.is_finite()).then_some(out)
}

#[inline]
fn hom(p: Vector2<f64>) -> Vector3<f64> {
    Vector3::new(p.x, p.y, 1.0)
}

/// Dehomogenises a point that must be finite; `None` if it is (numerically) at infinity.
#[inline]
fn finite(p: Vector3<f64>, scale_hint: f64) -> Option<Vector2<f64>> {
    if p.z.is_nan() || p.z.abs() <= 1e-12 * scale_hint {
        return None;
    }
    let q = Vector2::new(p.x / p.z, p.y / p.z);
    (q.x.is_finite() && q.y.is_finite()).then_some(q)
}

/// Checks that four points are finite and form a strictly convex quadrilateral (either
/// winding); returns twice its signed area (positive when clockwise in the image, whose v
/// axis points down).
pub(crate) fn convex_quad_area2(corners: &Corners) -> Result<f64, FiducialError> {
    if corners
        .iter()
        .any(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(FiducialError::BadQuad {
            reason: "a corner is not finite",
        });
    }
    let mut signs = [0.0f64; 4];
    for (i, s) in signs.iter_mut().enumerate() {
        let p0 = corners[i];
        let p1 = corners[(i + 1) % 4];
        let p2 = corners[(i + 2) % 4];
        *s = (p1 - p0).perp(&(p2 - p1));
    }
    let area2 = (0..4)
        .map(|i| corners[i].coords.perp(&corners[(i + 1) % 4].coords))
        .sum::<f64>();
    let scale: f64 = (0..4)
        .map(|i| (corners[(i + 1) % 4] - corners[i]).norm_squared())
        .sum();
    if !scale.is_finite() || scale <= 0.0 || !area2.is_finite() || area2.abs() <= 1e-12 * scale {
        return Err(FiducialError::BadQuad {
            reason: "the quadrilateral has no area",
        });
    }
    if !(signs.iter().all(|&s| s > 0.0) || signs.iter().all(|&s| s < 0.0)) {
        return Err(FiducialError::BadQuad {
            reason: "the quadrilateral is not convex",
        });
    }
    Ok(area2)
}

/// The same quad with its corners clockwise in the image (as [`crate::decode()`] wants):
/// unchanged if already clockwise, otherwise corner 0 kept and the others reversed.
pub fn clockwise(corners: &Corners) -> Result<Corners, FiducialError> {
    Ok(if convex_quad_area2(corners)? > 0.0 {
        *corners
    } else {
        [corners[0], corners[3], corners[2], corners[1]]
    })
}

impl CrossRatioFrame {
    /// Prepares the construction for corners `[q_NW, q_NE, q_SE, q_SW]`, which must form a
    /// strictly convex quadrilateral (either winding).
    pub fn new(corners: &Corners) -> Result<Self, FiducialError> {
        convex_quad_area2(corners)?;
        let origin = corners.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / 4.0;
        let scale = corners
            .iter()
            .map(|p| (p.coords - origin).norm())
            .sum::<f64>()
            / 4.0;
        let [nw, ne, se, sw] = corners.map(|p| hom((p.coords - origin) / scale));

        let bad = || FiducialError::BadQuad {
            reason: "degenerate geometry in the cross-ratio construction",
        };
        let centre = nw.cross(&se).cross(&sw.cross(&ne));
        // Vanishing points: possibly at infinity (third coordinate 0); never divided.
        let v1 = se.cross(&sw).cross(&ne.cross(&nw));
        let v2 = ne.cross(&se).cross(&nw.cross(&sw));
        let through_v1 = v1.cross(&centre);
        let through_v2 = v2.cross(&centre);
        let q_w = finite(nw.cross(&sw).cross(&through_v1), 1.0).ok_or_else(bad)?;
        let q_e = finite(ne.cross(&se).cross(&through_v1), 1.0).ok_or_else(bad)?;
        let q_n = finite(nw.cross(&ne).cross(&through_v2), 1.0).ok_or_else(bad)?;
        let q_s = finite(sw.cross(&se).cross(&through_v2), 1.0).ok_or_else(bad)?;
        let xy = |p: Vector3<f64>| Vector2::new(p.x, p.y);
        Ok(Self {
            top: Edge::new(xy(nw), q_n, xy(ne)).ok_or_else(bad)?,
            bottom: Edge::new(xy(sw), q_s, xy(se)).ok_or_else(bad)?,
            left: Edge::new(xy(nw), q_w, xy(sw)).ok_or_else(bad)?,
            right: Edge::new(xy(ne), q_e, xy(se)).ok_or_else(bad)?,
            origin,
            scale,
            h: square_to_quad([xy(nw), xy(ne), xy(se), xy(sw)]).ok_or_else(bad)?,
        })
    }

    /// The image of normalised marker coordinates `(a, b)` (`[-1, 1]^2` is the quad, `a`
    /// to the right, `b` down). Points somewhat outside the quad (e.g. the quiet zone) work
    /// too as long as they are in front of the horizon; `None` if the construction meets a
    /// point at infinity there or the input is not finite.
    #[inline]
    pub fn map(&self, a: f64, b: f64) -> Option<Point2<f64>> {
        if !(a.is_finite() && b.is_finite()) {
            return None;
        }
        self.image_of(self.homogeneous(a, b))
    }

    /// The homogeneous image `[x, y, w]` of normalised marker coordinates `(a, b)`, before
    /// the division by `w` (linear in `a` and `b`).
    #[inline]
    fn homogeneous(&self, a: f64, b: f64) -> [f64; 3] {
        let [h0, h1, h2, h3, h4, h5, h6, h7] = self.h;
        let (s, t) = (0.5 * (a + 1.0), 0.5 * (b + 1.0));
        [
            h0 * s + h1 * t + h2,
            h3 * s + h4 * t + h5,
            h6 * s + h7 * t + 1.0,
        ]
    }

    /// The image point of a homogeneous image; `None` beyond the horizon (or on it), where
    /// there is no image point (the construction's edge points run off to infinity there
    /// too), or when it is not finite.
    #[inline]
    fn image_of(&self, [x, y, w]: [f64; 3]) -> Option<Point2<f64>> {
        if w.is_nan() || w <= 1e-9 {
            return None;
        }
        let p = Vector2::new(x, y) / w;
        (p.x.is_finite() && p.y.is_finite()).then(|| Point2::from(self.origin + p * self.scale))
    }

    /// The segment from `(a0, b0)` to `(a1, b1)` (normalised marker coordinates, as in
    /// [`CrossRatioFrame::map`]), whose points [`FrameSegment::at`] maps: the homography is
    /// linear in homogeneous coordinates, so a point a fraction of the way along costs an
    /// interpolation and a division instead of a whole [`CrossRatioFrame::map`]. `None` if
    /// an end is not finite.
    pub(crate) fn segment(
        &self,
        (a0, b0): (f64, f64),
        (a1, b1): (f64, f64),
    ) -> Option<FrameSegment<'_>> {
        if !(a0.is_finite() && b0.is_finite() && a1.is_finite() && b1.is_finite()) {
            return None;
        }
        let (p, q) = (self.homogeneous(a0, b0), self.homogeneous(a1, b1));
        Some(FrameSegment {
            frame: self,
            start: p,
            delta: [q[0] - p[0], q[1] - p[1], q[2] - p[2]],
        })
    }

    /// [`CrossRatioFrame::map`] by the construction of the module documentation, point by
    /// point (edge points by cross ratio, then two lines intersected): the reference that
    /// `map`'s closed-form homography is tested against. Several times slower.
    pub fn map_by_construction(&self, a: f64, b: f64) -> Option<Point2<f64>> {
        if !(a.is_finite() && b.is_finite()) {
            return None;
        }
        let q_an = self.top.point(a)?;
        let q_as = self.bottom.point(a)?;
        let q_bw = self.left.point(b)?;
        let q_be = self.right.point(b)?;
        let p = finite(q_an.cross(&q_as).cross(&q_bw.cross(&q_be)), 1e-3)?;
        Some(Point2::from(self.origin + p * self.scale))
    }

    /// The centre (normalised coordinates) of cell `(col, row)` of a grid of `width x
    /// height` cells covering the quad.
    #[inline]
    pub fn cell_coords(col: f64, row: f64, width: f64, height: f64) -> (f64, f64) {
        (
            -1.0 + (2.0 * col + 1.0) / width,
            -1.0 + (2.0 * row + 1.0) / height,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> Point2<f64> {
        Point2::new(x, y)
    }

    #[test]
    fn square_maps_linearly() {
        let f = CrossRatioFrame::new(&[p(0.0, 0.0), p(10.0, 0.0), p(10.0, 10.0), p(0.0, 10.0)])
            .unwrap();
        let q = f.map(0.5, -0.5).unwrap();
        assert!((q - p(7.5, 2.5)).norm() < 1e-12, "{q}");
        let q = f.map(-1.0, 1.0).unwrap();
        assert!((q - p(0.0, 10.0)).norm() < 1e-12, "{q}");
    }

    /// The closed-form homography equals the construction, inside the quad and in its
    /// quiet zone, on a strongly perspective quad and an affine one.
    #[test]
    fn homography_equals_the_construction() {
        for c in [
            [p(10.0, 12.0), p(95.0, 20.0), p(80.0, 70.0), p(22.0, 60.0)],
            [p(0.0, 0.0), p(40.0, 10.0), p(50.0, 40.0), p(10.0, 30.0)],
            [
                p(300.0, 200.0),
                p(340.0, 205.0),
                p(338.0, 290.0),
                p(302.0, 280.0),
            ],
        ] {
            let f = CrossRatioFrame::new(&c).unwrap();
            for i in 0..=12 {
                for j in 0..=12 {
                    let (a, b) = (-1.4 + 0.233 * f64::from(i), -1.4 + 0.233 * f64::from(j));
                    let (x, y) = (f.map(a, b).unwrap(), f.map_by_construction(a, b).unwrap());
                    assert!((x - y).norm() < 1e-9, "({a}, {b}) on {c:?}: {x} vs {y}");
                }
            }
        }
    }

    #[test]
    fn clockwise_fixes_winding() {
        let cw = [p(0.0, 0.0), p(4.0, 0.0), p(4.0, 3.0), p(0.0, 3.0)];
        assert_eq!(clockwise(&cw).unwrap(), cw);
        let ccw = [cw[0], cw[3], cw[2], cw[1]];
        assert_eq!(clockwise(&ccw).unwrap(), cw);
        assert!(convex_quad_area2(&cw).unwrap() > 0.0);
    }

    #[test]
    fn rejects_bad_quads() {
        let nan = f64::NAN;
        assert!(
            CrossRatioFrame::new(&[p(nan, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]).is_err()
        );
        // Collinear.
        assert!(
            CrossRatioFrame::new(&[p(0.0, 0.0), p(1.0, 0.0), p(2.0, 0.0), p(3.0, 0.0)]).is_err()
        );
        // Bow tie.
        assert!(
            CrossRatioFrame::new(&[p(0.0, 0.0), p(1.0, 1.0), p(1.0, 0.0), p(0.0, 1.0)]).is_err()
        );
        // Concave (arrow head).
        assert!(
            CrossRatioFrame::new(&[p(0.0, 0.0), p(4.0, 0.0), p(1.0, 1.0), p(0.0, 4.0)]).is_err()
        );
    }
}
