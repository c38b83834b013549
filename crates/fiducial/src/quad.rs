//! Quadrilateral fitting: four corners from a traced contour (spec 3.4, step 3).
//!
//! A polygonal approximation limited to four vertices, in the manner of Douglas-Peucker but
//! greedy and bounded: the contour point farthest from the centroid is a vertex of any convex
//! outline, the point farthest from it is another; then the point farthest from its chord is
//! added twice, on whichever arc deviates most. Each vertex is then re-chosen as the point
//! farthest from the chord of its two neighbours (twice round): when a side is parallel to
//! the first chord (a trapezoid seen obliquely) all its points tie and the greedy choice
//! may lie far from the corner. The result is accepted only if every contour
//! point lies close to its side (a straightness tolerance that grows slowly with the side, to
//! allow for blur and digitisation), the quadrilateral is convex and clockwise in the image,
//! its sides are long enough and its corner angles are not too sharp (perspective makes them
//! deviate from 90 degrees, so the tolerance is generous). Every step is linear in the
//! contour length and allocates nothing.

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
pub fn fit_quad(contour: &[[i32; 2]], limits: &QuadLimits) -> Option<[[f64; 2]; 4]> {
    let n = contour.len();
    if n < 8 {
        return None;
    }
    let p = |i: usize| -> [f64; 2] {
        let q = contour[i % n];
        [f64::from(q[0]), f64::from(q[1])]
    };
    let (mut cx, mut cy) = (0.0, 0.0);
    for q in contour {
        cx += f64::from(q[0]);
        cy += f64::from(q[1]);
    }
    cx /= n as f64;
    cy /= n as f64;
    let far_from = |x: f64, y: f64| -> usize {
        let mut best = (0usize, -1.0f64);
        for (i, q) in contour.iter().enumerate() {
            let d = (f64::from(q[0]) - x).powi(2) + (f64::from(q[1]) - y).powi(2);
            if d > best.1 {
                best = (i, d);
            }
        }
        best.0
    };
    let i0 = far_from(cx, cy);
    let [x0, y0] = p(i0);
    let i2 = far_from(x0, y0);
    if i2 == i0 {
        return None;
    }
    // Farthest point strictly inside the circular arc a -> b from the chord p(a) p(b).
    let farthest = |a: usize, b: usize| -> (usize, f64) {
        let [ax, ay] = p(a);
        let [bx, by] = p(b);
        let (dx, dy) = (bx - ax, by - ay);
        let len = (dx * dx + dy * dy).sqrt().max(1e-9);
        let span = (b + n - a) % n;
        let mut best = (a, 0.0f64);
        for k in 1..span {
            let i = (a + k) % n;
            let [qx, qy] = p(i);
            let d = ((qx - ax) * dy - (qy - ay) * dx).abs() / len;
            if d > best.1 {
                best = (i, d);
            }
        }
        best
    };
    // Vertices in contour order, kept as contour indices.
    let (first, second) = if i0 < i2 { (i0, i2) } else { (i2, i0) };
    let mut v = [first, second, 0, 0];
    let mut count = 2;
    while count < 4 {
        let mut best = (usize::MAX, 0usize, -1.0f64); // (arc start slot, point, deviation)
        for s in 0..count {
            let (a, b) = (v[s], v[(s + 1) % count]);
            let (i, d) = farthest(a, b);
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
    // The first two vertices are the farthest pair, and the others the farthest from a chord
    // through them; when two sides are parallel (a face turned about an axis parallel to
    // them: a trapezoid), every point of the side opposite that chord is equally far and the
    // vertex chosen may lie anywhere along it. Each vertex is therefore re-chosen as the
    // farthest point from the chord of its two neighbours, which is a true corner whenever
    // those neighbours are (two rounds settle every case seen). A vertex moves only to a
    // point farther from the chord *and* more than 1.5 px away: two contour points within a
    // diagonal step of each other are the same corner to digitisation, and a small marker
    // whose border the threshold notched keeps its first, equally good vertex.
    for _ in 0..2 {
        for i in 0..4 {
            let (a, b) = (v[(i + 3) % 4], v[(i + 1) % 4]);
            let (k, d) = farthest(a, b);
            let [ax, ay] = p(a);
            let [bx, by] = p(b);
            let [qx, qy] = p(v[i]);
            let [kx, ky] = p(k);
            let (dx, dy) = (bx - ax, by - ay);
            let current = ((qx - ax) * dy - (qy - ay) * dx).abs() / dx.hypot(dy).max(1e-9);
            if d > current && (kx - qx).hypot(ky - qy) > 1.5 {
                v[i] = k;
            }
        }
    }
    // Each arc must be straight. Blur and the threshold blunt the corners, so the vertices
    // found may sit a pixel or more inside the true corners (most on small, sharp-cornered
    // views): a line is fitted to the middle two thirds of each arc, those points must lie
    // within the tolerance of it, and the corners are the intersections of adjacent lines.
    let mut lines = [[0.0f64; 3]; 4];
    for s in 0..4 {
        let (a, b) = (v[s], v[(s + 1) % 4]);
        let [ax, ay] = p(a);
        let [bx, by] = p(b);
        let len = (bx - ax).hypot(by - ay);
        if len < limits.min_side {
            return None;
        }
        let span = (b + n - a) % n;
        let trim = span / 6;
        let line = fit_line(contour, a + trim, span + 1 - 2 * trim)?;
        let tol = limits.line_tolerance + limits.line_tolerance_rel * len;
        for k in trim..=span - trim {
            let [qx, qy] = p(a + k);
            if (line[0] * qx + line[1] * qy - line[2]).abs() > tol {
                return None;
            }
        }
        lines[s] = line;
    }
    let mut corners = [[0.0; 2]; 4];
    for (i, c) in corners.iter_mut().enumerate() {
        let (l1, l2) = (lines[(i + 3) % 4], lines[i]);
        let det = l1[0] * l2[1] - l1[1] * l2[0];
        if det.abs() < 1e-6 {
            return None;
        }
        let x = (l1[2] * l2[1] - l2[2] * l1[1]) / det;
        let y = (l1[0] * l2[2] - l2[0] * l1[2]) / det;
        let [vx, vy] = p(v[i]);
        // The intersection must stay near the vertex found (not run off along a side).
        let moved = (x - vx).hypot(y - vy);
        if moved.is_nan() || moved > 0.25 * limits.min_side.max(4.0) + 3.0 {
            return None;
        }
        *c = [x, y];
    }
    if !convex_clockwise(&corners, limits.min_angle_deg) {
        return None;
    }
    Some(corners)
}

/// Total-least-squares line `[nx, ny, c]` (`nx x + ny y = c`, unit normal) through `count`
/// contour points from index `from` (circular).
fn fit_line(contour: &[[i32; 2]], from: usize, count: usize) -> Option<[f64; 3]> {
    let n = contour.len();
    if count < 2 {
        return None;
    }
    let (mut mx, mut my) = (0.0, 0.0);
    for k in 0..count {
        let q = contour[(from + k) % n];
        mx += f64::from(q[0]);
        my += f64::from(q[1]);
    }
    mx /= count as f64;
    my /= count as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for k in 0..count {
        let q = contour[(from + k) % n];
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
pub fn convex_clockwise(c: &[[f64; 2]; 4], min_angle_deg: f64) -> bool {
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
        let mut got: Vec<[f64; 2]> = q.iter().map(|c| [c[0].round(), c[1].round()]).collect();
        assert!(q.iter().flatten().all(|v| (v - v.round()).abs() < 1e-9));
        got.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(
            got,
            vec![[3.0, 4.0], [3.0, 15.0], [22.0, 4.0], [22.0, 15.0]]
        );
        assert!(convex_clockwise(&q, 30.0));
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
        let ccw = [[0.0, 0.0], [0.0, 10.0], [10.0, 10.0], [10.0, 0.0]];
        assert!(!convex_clockwise(&ccw, 30.0));
        let sharp = [[0.0, 0.0], [100.0, 0.0], [100.0, 5.0], [0.0, 10.0]];
        assert!(convex_clockwise(&sharp, 1.0));
        assert!(!convex_clockwise(&sharp, 89.0));
    }
}
