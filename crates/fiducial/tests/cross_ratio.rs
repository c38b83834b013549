//! The cross-ratio construction of spec 3.5 equals the homography fixed by the corners.

use fiducial::{Corners, CrossRatioFrame};
use nalgebra::{Matrix3, Point2, SMatrix, SVector, Vector3};
use proptest::prelude::*;

/// The homography taking (-1,-1), (1,-1), (1,1), (-1,1) to the corners (direct linear
/// transform with h33 = 1), solved independently of the crate.
fn homography(c: &Corners) -> Matrix3<f64> {
    let src = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut rhs = SVector::<f64, 8>::zeros();
    for (i, (&(x, y), p)) in src.iter().zip(c).enumerate() {
        let (u, v) = (p.x, p.y);
        let r = 2 * i;
        a.row_mut(r)
            .copy_from_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]);
        a.row_mut(r + 1)
            .copy_from_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]);
        rhs[r] = u;
        rhs[r + 1] = v;
    }
    let h = a
        .full_piv_lu()
        .solve(&rhs)
        .expect("corners in general position");
    Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0)
}

fn apply(h: &Matrix3<f64>, a: f64, b: f64) -> Point2<f64> {
    let p = h * Vector3::new(a, b, 1.0);
    Point2::new(p.x / p.z, p.y / p.z)
}

fn size(c: &Corners) -> f64 {
    (c[2] - c[0]).norm().max((c[3] - c[1]).norm())
}

fn is_convex_clockwise(c: &Corners) -> bool {
    (0..4).all(|i| {
        let (p0, p1, p2) = (c[i], c[(i + 1) % 4], c[(i + 2) % 4]);
        (p1 - p0).perp(&(p2 - p1)) > 1e-3 * size(c) * size(c)
    })
}

/// Convex quads: points at increasing angles round a centre, radii varied; kept when
/// strictly convex. Coordinates span image-like ranges.
fn convex_quad() -> impl Strategy<Value = Corners> {
    (
        (-2000.0..2000.0f64, -2000.0..2000.0f64),
        1.0..500.0f64,
        0.0..std::f64::consts::TAU,
        prop::array::uniform4(0.15..1.0f64),
        prop::array::uniform4(0.4..1.0f64),
    )
        .prop_map(|((cx, cy), r, start, gaps, radii)| {
            let total: f64 = gaps.iter().sum();
            let mut angle = start;
            core::array::from_fn(|i| {
                let p = Point2::new(
                    cx + r * radii[i] * angle.cos(),
                    cy + r * radii[i] * angle.sin(),
                );
                angle += gaps[i] / total * std::f64::consts::TAU;
                p
            })
        })
        .prop_filter("strictly convex", is_convex_clockwise)
}

/// Parallelograms (affine views: both vanishing points at infinity).
fn parallelogram() -> impl Strategy<Value = Corners> {
    (
        (-2000.0..2000.0f64, -2000.0..2000.0f64),
        (1.0..400.0f64, -100.0..100.0f64),
        (-100.0..100.0f64, 1.0..400.0f64),
    )
        .prop_map(|((x, y), (ux, uy), (vx, vy))| {
            let p0 = Point2::new(x, y);
            let (u, v) = (
                nalgebra::Vector2::new(ux, uy),
                nalgebra::Vector2::new(vx, vy),
            );
            [p0, p0 + u, p0 + u + v, p0 + v]
        })
        .prop_filter("strictly convex", is_convex_clockwise)
}

fn check(c: &Corners, a: f64, b: f64) -> Result<(), TestCaseError> {
    let frame = CrossRatioFrame::new(c).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let want = apply(&homography(c), a, b);
    // Both the closed form `map` evaluates and the construction itself.
    for got in [frame.map(a, b), frame.map_by_construction(a, b)] {
        let got = got.ok_or_else(|| TestCaseError::fail("no point"))?;
        let err = (got - want).norm();
        prop_assert!(
            err <= 1e-9 * size(c),
            "({a}, {b}) on {c:?}: cross ratio {got} vs homography {want}, error {err}"
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn equals_homography_on_convex_quads(c in convex_quad(), a in -1.0..=1.0f64, b in -1.0..=1.0f64) {
        check(&c, a, b)?;
    }

    #[test]
    fn equals_homography_on_parallelograms(c in parallelogram(), a in -1.0..=1.0f64, b in -1.0..=1.0f64) {
        check(&c, a, b)?;
    }

    /// The corners themselves and either winding.
    #[test]
    fn corners_map_to_themselves_in_either_winding(c in convex_quad()) {
        let reversed = [c[1], c[0], c[3], c[2]];
        for quad in [c, reversed] {
            let f = CrossRatioFrame::new(&quad).unwrap();
            for (i, (a, b)) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)].into_iter().enumerate() {
                let p = f.map(a, b).unwrap();
                prop_assert!((p - quad[i]).norm() <= 1e-9 * size(&quad));
            }
        }
    }
}

/// Exact parallelograms (integer corners): the vanishing points have third coordinate
/// exactly 0 and the construction must still work.
#[test]
fn exact_affine_view() {
    let c = [
        Point2::new(10.0, 20.0),
        Point2::new(110.0, 40.0),
        Point2::new(130.0, 140.0),
        Point2::new(30.0, 120.0),
    ];
    let f = CrossRatioFrame::new(&c).unwrap();
    let p = f.map(0.5, -0.25).unwrap();
    // Affine: p = centre + a/2 (NE - NW) + b/2 (SW - NW).
    let centre = Point2::new(70.0, 80.0);
    let want = centre + 0.25 * (c[1] - c[0]) - 0.125 * (c[3] - c[0]);
    assert!((p - want).norm() < 1e-9, "{p} vs {want}");
}

/// The quiet zone (just outside the quad) maps as the homography does.
#[test]
fn extends_outside_the_quad() {
    let c = [
        Point2::new(100.0, 100.0),
        Point2::new(300.0, 120.0),
        Point2::new(280.0, 260.0),
        Point2::new(110.0, 230.0),
    ];
    let f = CrossRatioFrame::new(&c).unwrap();
    let h = homography(&c);
    for (a, b) in [(-1.2, -1.2), (1.2, 0.3), (0.0, 1.25), (-1.1, 1.1)] {
        let got = f.map(a, b).unwrap();
        let want = apply(&h, a, b);
        assert!(
            (got - want).norm() < 1e-9 * size(&c),
            "({a}, {b}): {got} vs {want}"
        );
    }
}
