//! Quadrilateral fitting: four corners from a traced contour (spec 3.4, step 3).
//!
//! A polygonal approximation limited to four vertices, in the manner of Douglas-Peucker but
//! greedy and bounded: the contour point farthest from the centroid is a vertex of any convex
//! outline, the point farthest from it is another; then the point farthest from its chord is
//! added twice, on whichever arc deviates most. Each vertex is then re-chosen as the point
//! farthest from the chord of its two neighbours (twice round): when a side is parallel to
//! the first chord (a trapezoid seen obliquely) all its points tie and the greedy choice
//! may lie far from the corner. The result is accepted only if every contour point lies
//! close to its side (a straightness tolerance that grows slowly with the side, to allow for
//! blur and digitisation) or, on a side the threshold notched (a thin border broken by a
//! white data cell, on small oblique markers), if no point sticks out and at most half of
//! them lie in inward dents; and only if the quadrilateral is convex and clockwise in the
//! image, its sides are long enough and its corner angles are not too sharp (perspective
//! makes them deviate from 90 degrees, so the tolerance is generous). Every step is linear
//! in the contour length and allocates nothing.

use crate::image::Corners;
use nalgebra::Point2;

/// Limits on an acceptable quadrilateral.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadLimits {
    /// Shortest side accepted, in pixels.
    pub min_side: f64,
    /// Smallest interior angle accepted, in degrees (largest is 180 minus this).
    pub min_angle_deg: f64,
    /// Absolute part of the straightness tolerance, in pixels.
    pub line_tolerance: f64,
    /// Relative part of the straightness tolerance (times the side length).
    pub line_tolerance_rel: f64,
}

/// Fits four corners (pixel coordinates of contour points, clockwise in the image) to a closed
/// contour, or `None` if the contour is not a quadrilateral within `limits`.
pub fn fit_quad(contour: &[[i32; 2]], limits: &QuadLimits) -> Option<Corners> {
    if contour.len() < 8 {
        return None;
    }
    let contour = Contour(contour);
    let mut v = contour.greedy_vertices()?;
    contour.settle_vertices(&mut v);
    let lines = contour.side_lines(&v, limits)?;
    let corners = contour.corners(&lines, &v, limits)?;
    convex_clockwise(&corners, limits.min_angle_deg).then_some(corners)
}

/// A closed contour (at least 8 points) and the point searches of the quad fit.
#[derive(Clone, Copy)]
struct Contour<'a>(&'a [[i32; 2]]);

impl Contour<'_> {
    fn len(&self) -> usize {
        self.0.len()
    }

    /// Point `i` (circular) as pixel coordinates.
    #[inline]
    fn p(&self, i: usize) -> [f64; 2] {
        let q = self.0[i % self.len()];
        [f64::from(q[0]), f64::from(q[1])]
    }

    /// The first point farthest from `(x, y)`.
    fn farthest_from_point(&self, x: f64, y: f64) -> usize {
        let mut best = (0usize, -1.0f64);
        for (i, q) in self.0.iter().enumerate() {
            let d = (f64::from(q[0]) - x).powi(2) + (f64::from(q[1]) - y).powi(2);
            if d > best.1 {
                best = (i, d);
            }
        }
        best.0
    }

    /// The point strictly inside the circular arc `a -> b` farthest from the chord
    /// `p(a) p(b)`, and its distance (`(a, 0)` when none is off the chord).
    fn farthest_from_chord(&self, a: usize, b: usize) -> (usize, f64) {
        let n = self.len();
        let [ax, ay] = self.p(a);
        let [bx, by] = self.p(b);
        let (dx, dy) = (bx - ax, by - ay);
        let len = (dx * dx + dy * dy).sqrt().max(1e-9);
        let span = (b + n - a) % n;
        // (offset from a, distance times `len`); the index is taken modulo once, and the
        // distance divided once, at the end. Contour points are integers, so the cross
        // products are exact and the largest of them is the largest distance.
        let mut best = (0, 0.0f64);
        for (k, q) in arc(self.0, a + 1, span.saturating_sub(1)).enumerate() {
            let (qx, qy) = (f64::from(q[0]), f64::from(q[1]));
            let d = ((qx - ax) * dy - (qy - ay) * dx).abs();
            if d > best.1 {
                best = (k + 1, d);
            }
        }
        ((a + best.0) % n, best.1 / len)
    }

    /// Four vertices in contour order (contour indices): the point farthest from the
    /// centroid, the point farthest from it, then twice the point farthest from its chord on
    /// whichever arc deviates most. `None` for a contour with no such four points.
    fn greedy_vertices(&self) -> Option<[usize; 4]> {
        let n = self.len();
        let (mut cx, mut cy) = (0.0, 0.0);
        for q in self.0 {
            cx += f64::from(q[0]);
            cy += f64::from(q[1]);
        }
        cx /= n as f64;
        cy /= n as f64;
        let i0 = self.farthest_from_point(cx, cy);
        let [x0, y0] = self.p(i0);
        let i2 = self.farthest_from_point(x0, y0);
        if i2 == i0 {
            return None;
        }
        let (first, second) = if i0 < i2 { (i0, i2) } else { (i2, i0) };
        let mut v = [first, second, 0, 0];
        let mut count = 2;
        while count < 4 {
            let mut best = (usize::MAX, 0usize, -1.0f64); // (arc start slot, point, deviation)
            for s in 0..count {
                let (a, b) = (v[s], v[(s + 1) % count]);
                let (i, d) = self.farthest_from_chord(a, b);
                if d > best.2 {
                    best = (s, i, d);
                }
            }
            if best.2 <= 0.0 || best.0 == usize::MAX {
                return None;
            }
            // Insert after slot best.0, keeping contour order.
            let slot = best.0 + 1;
            for k in (slot..count).rev() {
                v[k + 1] = v[k];
            }
            v[slot] = best.1;
            count += 1;
        }
        Some(v)
    }

    /// Re-chooses each vertex as the point farthest from the chord of its two neighbours.
    ///
    /// The first two vertices are the farthest pair, and the others the farthest from a chord
    /// through them; when two sides are parallel (a face turned about an axis parallel to
    /// them: a trapezoid), every point of the side opposite that chord is equally far and the
    /// vertex chosen may lie anywhere along it. Re-chosen this way a vertex is a true corner
    /// whenever its neighbours are (two rounds settle every case seen). A vertex moves only
    /// to a point farther from the chord *and* more than 1.5 px away: two contour points
    /// within a diagonal step of each other are the same corner to digitisation, and a small
    /// marker whose border the threshold notched keeps its first, equally good vertex.
    fn settle_vertices(&self, v: &mut [usize; 4]) {
        for _ in 0..2 {
            for i in 0..4 {
                let (a, b) = (v[(i + 3) % 4], v[(i + 1) % 4]);
                let (k, d) = self.farthest_from_chord(a, b);
                let [ax, ay] = self.p(a);
                let [bx, by] = self.p(b);
                let [qx, qy] = self.p(v[i]);
                let [kx, ky] = self.p(k);
                let (dx, dy) = (bx - ax, by - ay);
                let current = ((qx - ax) * dy - (qy - ay) * dx).abs() / dx.hypot(dy).max(1e-9);
                if d > current && (kx - qx).hypot(ky - qy) > 1.5 {
                    v[i] = k;
                }
            }
        }
    }

    /// The line of each side `v[s] -> v[s + 1]`, or `None` if a side is too short or not
    /// straight.
    ///
    /// Blur and the threshold blunt the corners, so the vertices found may sit a pixel or
    /// more inside the true corners (most on small, sharp-cornered views): a line is fitted
    /// to the middle two thirds of each arc, and those points must lie within the tolerance
    /// of it (see [`Contour::notched_side_line`] for a side the threshold notched).
    fn side_lines(&self, v: &[usize; 4], limits: &QuadLimits) -> Option<[[f64; 3]; 4]> {
        let n = self.len();
        let mut lines = [[0.0f64; 3]; 4];
        let inside = v.iter().fold([0.0, 0.0], |m, &i| {
            let [x, y] = self.p(i);
            [m[0] + x / 4.0, m[1] + y / 4.0]
        });
        for s in 0..4 {
            let (a, b) = (v[s], v[(s + 1) % 4]);
            let [ax, ay] = self.p(a);
            let [bx, by] = self.p(b);
            let len = (bx - ax).hypot(by - ay);
            if len < limits.min_side {
                return None;
            }
            let span = (b + n - a) % n;
            let trim = span / 6;
            let (from, count) = (a + trim, span + 1 - 2 * trim);
            let tol = limits.line_tolerance + limits.line_tolerance_rel * len;
            let line = fit_line(self.0, from, count, None)?;
            lines[s] = if deviations(self.0, from, count, &line, tol, inside).straight() {
                line
            } else {
                self.notched_side_line((a, b), (from, count), tol, inside)?
            };
        }
        Some(lines)
    }

    /// The line of a side that is not straight, if it is a notched one.
    ///
    /// On a small or oblique marker whose border is one or two pixels wide, blur lets a white
    /// data cell break through the border in the binary image, and the contour dives into the
    /// marker there. Such dents only go inwards and leave most of the side on its line:
    /// starting from the chord of the two vertices (which blunted or bulging corners may put
    /// a pixel off the side), the line is refitted three times to the points not more than
    /// the tolerance, then less, then `DENT_BAND` inside it, and the side is accepted if no
    /// point sticks out beyond the tolerance and at most half of them are in dents (the
    /// grey-level refinement never sees the binary image).
    fn notched_side_line(
        &self,
        (a, b): (usize, usize),
        (from, count): (usize, usize),
        tol: f64,
        inside: [f64; 2],
    ) -> Option<[f64; 3]> {
        let mut line = chord_line(self.p(a), self.p(b))?;
        for band in [tol, 0.5 * (tol + DENT_BAND), DENT_BAND] {
            line = fit_line(self.0, from, count, Some((&line, inside, tol, band)))?;
        }
        let d = deviations(self.0, from, count, &line, tol, inside);
        if d.outward > 0 || 2 * d.inward > count {
            return None;
        }
        Some(line)
    }

    /// The corners: intersections of adjacent side lines, each of which must stay near the
    /// vertex found (not run off along a side).
    fn corners(
        &self,
        lines: &[[f64; 3]; 4],
        v: &[usize; 4],
        limits: &QuadLimits,
    ) -> Option<Corners> {
        let mut corners = [Point2::origin(); 4];
        for (i, c) in corners.iter_mut().enumerate() {
            let (l1, l2) = (lines[(i + 3) % 4], lines[i]);
            let det = l1[0] * l2[1] - l1[1] * l2[0];
            if det.abs() < 1e-6 {
                return None;
            }
            let x = (l1[2] * l2[1] - l2[2] * l1[1]) / det;
            let y = (l1[0] * l2[2] - l2[0] * l1[2]) / det;
            let [vx, vy] = self.p(v[i]);
            let moved = (x - vx).hypot(y - vy);
            if moved.is_nan() || moved > 0.25 * limits.min_side.max(4.0) + 3.0 {
                return None;
            }
            *c = Point2::new(x, y);
        }
        Some(corners)
    }
}

/// How far inside a notched side's line its points may lie and still be fitted in the end,
/// pixels: a digital straight edge stays within half a pixel of its line, the walls of a
/// dent do not.
const DENT_BAND: f64 = 0.75;

/// Points of a side off its line by more than the tolerance: `outward` (away from the
/// quad's inside) and `inward`.
#[derive(Debug, Clone, Copy)]
struct Deviations {
    outward: usize,
    inward: usize,
}

impl Deviations {
    fn straight(&self) -> bool {
        self.outward == 0 && self.inward == 0
    }
}

/// Counts the `count` contour points from `from` (circular) farther than `tol` from `line`,
/// on either side of it; `inside` is a point inside the quadrilateral.
fn deviations(
    contour: &[[i32; 2]],
    from: usize,
    count: usize,
    line: &[f64; 3],
    tol: f64,
    inside: [f64; 2],
) -> Deviations {
    let inner = (line[0] * inside[0] + line[1] * inside[1] - line[2]).signum();
    let mut d = Deviations {
        outward: 0,
        inward: 0,
    };
    for q in arc(contour, from, count) {
        let e = line[0] * f64::from(q[0]) + line[1] * f64::from(q[1]) - line[2];
        if e.abs() > tol || e.is_nan() {
            if e * inner > 0.0 {
                d.inward += 1;
            } else {
                d.outward += 1;
            }
        }
    }
    d
}

/// The `count` points of `contour` from index `from`, going round (`count` at most the
/// length): two slices chained, so that no point costs a modulo.
fn arc(contour: &[[i32; 2]], from: usize, count: usize) -> impl Iterator<Item = [i32; 2]> + '_ {
    let from = if contour.is_empty() {
        0
    } else {
        from % contour.len()
    };
    contour[from..]
        .iter()
        .chain(&contour[..from])
        .take(count)
        .copied()
}

/// The line `[nx, ny, c]` through two points, or `None` if they coincide.
fn chord_line(a: [f64; 2], b: [f64; 2]) -> Option<[f64; 3]> {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dy);
    if len.is_nan() || len < 1e-9 {
        return None;
    }
    let (nx, ny) = (-dy / len, dx / len);
    Some([nx, ny, nx * a[0] + ny * a[1]])
}

/// Total-least-squares line `[nx, ny, c]` (`nx x + ny y = c`, unit normal) through `count`
/// contour points from index `from` (circular). With `outer = Some((line, inside, tol,
/// band))`, only through those of them not more than `band` px from `line` towards `inside`
/// nor more than `tol` px away from it: the outermost points of a side whose dents all go
/// inwards, without the points that stick out (which then reject the side).
fn fit_line(
    contour: &[[i32; 2]],
    from: usize,
    count: usize,
    outer: Option<(&[f64; 3], [f64; 2], f64, f64)>,
) -> Option<[f64; 3]> {
    let keep = |q: [i32; 2]| {
        outer.is_none_or(|(l, inside, tol, band)| {
            let inner = (l[0] * inside[0] + l[1] * inside[1] - l[2]).signum();
            let e = (l[0] * f64::from(q[0]) + l[1] * f64::from(q[1]) - l[2]) * inner;
            (-tol..=band).contains(&e)
        })
    };
    let (mut mx, mut my, mut m) = (0.0, 0.0, 0usize);
    for q in arc(contour, from, count) {
        if keep(q) {
            mx += f64::from(q[0]);
            my += f64::from(q[1]);
            m += 1;
        }
    }
    if m < 2 {
        return None;
    }
    mx /= m as f64;
    my /= m as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for q in arc(contour, from, count) {
        if !keep(q) {
            continue;
        }
        let (dx, dy) = (f64::from(q[0]) - mx, f64::from(q[1]) - my);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (nx, ny) = (-theta.sin(), theta.cos());
    Some([nx, ny, nx * mx + ny * my])
}

/// True when the four corners form a convex quadrilateral, clockwise in the image (v down),
/// with every interior angle between `min_angle_deg` and `180 - min_angle_deg`.
pub fn convex_clockwise(c: &Corners, min_angle_deg: f64) -> bool {
    let max_cos = min_angle_deg.to_radians().cos();
    for i in 0..4 {
        let a = c[(i + 3) % 4];
        let b = c[i];
        let d = c[(i + 1) % 4];
        let e1 = [b[0] - a[0], b[1] - a[1]];
        let e2 = [d[0] - b[0], d[1] - b[1]];
        let cross = e1[0] * e2[1] - e1[1] * e2[0];
        let n1 = (e1[0] * e1[0] + e1[1] * e1[1]).sqrt();
        let n2 = (e2[0] * e2[0] + e2[1] * e2[1]).sqrt();
        if cross.is_nan() || cross <= 0.0 || n1 == 0.0 || n2 == 0.0 {
            return false;
        }
        // Interior angle = 180 - turning angle; its cosine is -cos(turn).
        let cos_interior = -(e1[0] * e2[0] + e1[1] * e2[1]) / (n1 * n2);
        if cos_interior.abs() > max_cos {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: QuadLimits = QuadLimits {
        min_side: 5.0,
        min_angle_deg: 30.0,
        line_tolerance: 1.0,
        line_tolerance_rel: 0.04,
    };

    /// The clockwise boundary of an axis-aligned w x h rectangle of pixels at (x0, y0).
    fn rect_contour(x0: i32, y0: i32, w: i32, h: i32) -> Vec<[i32; 2]> {
        let mut c = Vec::new();
        for x in x0..x0 + w - 1 {
            c.push([x, y0]);
        }
        for y in y0..y0 + h - 1 {
            c.push([x0 + w - 1, y]);
        }
        for x in (x0 + 1..x0 + w).rev() {
            c.push([x, y0 + h - 1]);
        }
        for y in (y0 + 1..y0 + h).rev() {
            c.push([x0, y]);
        }
        c
    }

    #[test]
    fn rectangle_gives_its_corners_clockwise() {
        let c = rect_contour(3, 4, 20, 12);
        let q = fit_quad(&c, &LIMITS).unwrap();
        let mut got: Vec<[f64; 2]> = q.iter().map(|c| [c.x.round(), c.y.round()]).collect();
        assert!(
            q.iter()
                .flat_map(|c| [c.x, c.y])
                .all(|v| (v - v.round()).abs() < 1e-9)
        );
        got.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(
            got,
            vec![[3.0, 4.0], [3.0, 15.0], [22.0, 4.0], [22.0, 15.0]]
        );
        assert!(convex_clockwise(&q, 30.0));
    }

    /// The traced outer contour of the dark pixels of `mask` (rows of `#` and `.`, with a
    /// light margin of at least one pixel).
    fn traced(mask: &[&str]) -> Vec<[i32; 2]> {
        let w = mask[0].len();
        let bin: Vec<u8> = mask
            .iter()
            .flat_map(|r| r.bytes().map(|b| u8::from(b == b'#')))
            .collect();
        let first = bin.iter().position(|&b| b == 1).unwrap();
        let mut c = Vec::new();
        assert!(crate::contour::trace_outer(
            &bin,
            w,
            (first % w) as u32,
            (first / w) as u32,
            10_000,
            &mut c
        ));
        c
    }

    /// A 16 x 30 dark rectangle at (6, 2) in a 28 x 34 mask, with `edit` applied to its rows.
    fn mask_with(edit: impl Fn(usize, &mut Vec<u8>)) -> Vec<String> {
        (0..34)
            .map(|y| {
                let mut row: Vec<u8> = (0..28)
                    .map(|x| {
                        if (6..22).contains(&x) && (2..32).contains(&y) {
                            b'#'
                        } else {
                            b'.'
                        }
                    })
                    .collect();
                edit(y, &mut row);
                String::from_utf8(row).unwrap()
            })
            .collect()
    }

    const MARKER_LIMITS: QuadLimits = QuadLimits {
        min_side: 10.0,
        min_angle_deg: 30.0,
        line_tolerance: 1.5,
        line_tolerance_rel: 0.05,
    };

    #[test]
    fn a_border_notched_by_the_threshold_still_gives_a_quad() {
        // Regression (random scene 85): a marker 14 px wide at 68 degrees off-axis has a
        // border two pixels wide, and blur let white data cells break through it in the
        // binary image, so the contour dived up to 7 px into the marker on two rows. The
        // dents go inwards only; the corners must still be the rectangle's.
        let rows = mask_with(|y, row| {
            if y == 10 {
                row[6..10].fill(b'.');
            }
            if y == 22 || y == 23 {
                row[6..13].fill(b'.');
            }
        });
        let mask: Vec<&str> = rows.iter().map(String::as_str).collect();
        let q = fit_quad(&traced(&mask), &MARKER_LIMITS).expect("notched rectangle rejected");
        let mut got: Vec<[f64; 2]> = q.iter().map(|c| [c.x.round(), c.y.round()]).collect();
        got.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(
            got,
            vec![[6.0, 2.0], [6.0, 31.0], [21.0, 2.0], [21.0, 31.0]]
        );
    }

    #[test]
    fn bumps_and_wide_bites_are_still_rejected() {
        // Something stuck to a side (an outward bump beyond the tolerance) is not a quad
        // side...
        let bump = mask_with(|y, row| {
            if (14..18).contains(&y) {
                row[1..6].fill(b'#');
            }
        });
        let mask: Vec<&str> = bump.iter().map(String::as_str).collect();
        assert!(fit_quad(&traced(&mask), &MARKER_LIMITS).is_none());
        // ...and a side more than half missing (a U shape) is not a notched one.
        let u = mask_with(|y, row| {
            if (7..28).contains(&y) {
                row[6..16].fill(b'.');
            }
        });
        let mask: Vec<&str> = u.iter().map(String::as_str).collect();
        assert!(fit_quad(&traced(&mask), &MARKER_LIMITS).is_none());
    }

    #[test]
    fn circle_is_rejected() {
        let mut c = Vec::new();
        for k in 0..200 {
            let t = k as f64 / 200.0 * std::f64::consts::TAU;
            c.push([
                (50.0 + 30.0 * t.cos()).round() as i32,
                (50.0 + 30.0 * t.sin()).round() as i32,
            ]);
        }
        assert!(fit_quad(&c, &LIMITS).is_none());
    }

    #[test]
    fn small_or_degenerate_is_rejected() {
        assert!(fit_quad(&rect_contour(0, 0, 4, 4), &LIMITS).is_none());
        assert!(fit_quad(&[[1, 1]; 20], &LIMITS).is_none());
        // A counter-clockwise square is not accepted as clockwise.
        let points = |c: [(f64, f64); 4]| c.map(|(x, y)| Point2::new(x, y));
        let ccw = points([(0.0, 0.0), (0.0, 10.0), (10.0, 10.0), (10.0, 0.0)]);
        assert!(!convex_clockwise(&ccw, 30.0));
        let sharp = points([(0.0, 0.0), (100.0, 0.0), (100.0, 5.0), (0.0, 10.0)]);
        assert!(convex_clockwise(&sharp, 1.0));
        assert!(!convex_clockwise(&sharp, 89.0));
    }
}
