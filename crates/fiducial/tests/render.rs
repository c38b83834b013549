//! Exact raster geometry and SVG output of rendered markers.

use fiducial::{FiducialError, MarkerFamily, RenderOptions, render_marker, render_svg};
use proptest::prelude::*;

const FIG4: u64 = 663_209;

#[test]
fn raster_geometry_is_exact() {
    let f = MarkerFamily::PAPER_4X5;
    let m = render_marker(
        f,
        FIG4,
        &RenderOptions {
            px_per_cell: 10,
            quiet_cells: 2,
        },
    )
    .unwrap();
    // 7 x 6 marker cells + 2 quiet cells a side, 10 px each.
    assert_eq!((m.width(), m.height()), (110, 100));
    let c = m.corners();
    assert_eq!((c[0].x, c[0].y), (19.5, 19.5));
    assert_eq!((c[1].x, c[1].y), (89.5, 19.5));
    assert_eq!((c[2].x, c[2].y), (89.5, 79.5));
    assert_eq!((c[3].x, c[3].y), (19.5, 79.5));
    let v = m.view();
    // The pixels either side of each border edge.
    assert_eq!(v.get(19, 19), Some(255));
    assert_eq!(v.get(20, 20), Some(0));
    assert_eq!(v.get(89, 79), Some(0));
    assert_eq!(v.get(90, 80), Some(255));
    // Data cell (row, col) occupies pixels from 20 + 10 (col + 1).
    let mut bits = [false; 64];
    for (k, &b) in f.bits_of(FIG4, &mut bits).iter().enumerate() {
        let (row, col) = (k / 5, k % 5);
        let (x, y) = (20 + 10 * (col + 1) + 5, 20 + 10 * (row + 1) + 5);
        assert_eq!(
            v.get(x, y),
            Some(if b { 0 } else { 255 }),
            "cell {row},{col}"
        );
    }
}

#[test]
fn svg_has_physical_size_and_every_black_cell() {
    let f = MarkerFamily::PAPER_4X5;
    let svg = render_svg(f, FIG4, 20.0, 1).unwrap();
    assert!(svg.contains("width=\"180mm\" height=\"160mm\""), "{svg}");
    assert!(svg.contains("viewBox=\"0 0 9 8\""));
    // Sum of the black runs' widths = black cells (border 22 + data popcount 10).
    let black: u32 = svg
        .lines()
        .filter(|l| l.contains("fill=\"#000\""))
        .map(|l| {
            let w = l.split("width=\"").nth(1).unwrap();
            w[..w.find('"').unwrap()].parse::<u32>().unwrap()
        })
        .sum();
    assert_eq!(black, 22 + FIG4.count_ones());
}

#[test]
fn bad_options_are_errors() {
    let f = MarkerFamily::PAPER_4X5;
    assert!(matches!(
        render_marker(
            f,
            FIG4,
            &RenderOptions {
                px_per_cell: 0,
                quiet_cells: 1
            }
        ),
        Err(FiducialError::BadRender { .. })
    ));
    assert!(matches!(
        render_marker(
            f,
            FIG4,
            &RenderOptions {
                px_per_cell: 4,
                quiet_cells: 0
            }
        ),
        Err(FiducialError::BadRender { .. })
    ));
    assert!(matches!(
        render_marker(f, 1 << 20, &RenderOptions::default()),
        Err(FiducialError::CodeOutOfRange { .. })
    ));
    assert!(render_svg(f, FIG4, f64::NAN, 1).is_err());
    assert!(render_svg(f, FIG4, -1.0, 1).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The count of black pixels is exactly (border + black data cells) * k^2.
    #[test]
    fn black_area_is_exact(code in 0u64..(1 << 20), k in 1u32..12, q in 1u32..4) {
        let f = MarkerFamily::PAPER_4X5;
        let m = render_marker(f, code, &RenderOptions { px_per_cell: k, quiet_cells: q }).unwrap();
        let black = m.pixels().iter().filter(|&&p| p == 0).count() as u32;
        prop_assert_eq!(black, (22 + code.count_ones()) * k * k);
        let c = m.corners();
        prop_assert_eq!(c[1].x - c[0].x, f64::from(7 * k));
        prop_assert_eq!(c[3].y - c[0].y, f64::from(6 * k));
    }
}
