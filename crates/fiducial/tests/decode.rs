//! Decoding rendered markers: exact corners, every corner order, bit flips, rejections.

use fiducial::{
    DecodeParams, Dictionary, GrayView, MarkerFamily, Rejection, RenderOptions, decode, hamming,
    render_marker,
};
use nalgebra::Point2;
use proptest::prelude::*;

fn shifted(c: &fiducial::Corners, j: usize) -> fiducial::Corners {
    core::array::from_fn(|i| c[(i + j) % 4])
}

#[test]
fn every_entry_decodes_from_every_corner_order() {
    let dict = Dictionary::paper();
    let params = DecodeParams::default();
    for (index, &code) in dict.codes().iter().enumerate() {
        let m = render_marker(dict.family(), code, &RenderOptions::default()).unwrap();
        let exact = m.corners();
        for j in 0..4 {
            let d = decode(&m.view(), &shifted(&exact, j), dict, &params)
                .unwrap_or_else(|e| panic!("entry {index}, shift {j}: {e}"));
            assert_eq!(d.index, index);
            assert_eq!(d.code, code);
            assert_eq!(d.distance, 0);
            assert_eq!(d.rotation as usize, (4 - j) % 4, "entry {index}, shift {j}");
            assert_eq!(d.corners, exact, "entry {index}, shift {j}");
            assert!(d.contrast > 250.0);
            assert!(d.confidence > 0.99, "{}", d.confidence);
        }
    }
}

#[test]
fn square_family_reads_all_four_rotations() {
    let family = MarkerFamily::new(4, 4).unwrap();
    let mut p = fiducial::GenerateParams::for_family(family, 5);
    p.max_codes = 12;
    let dict = Dictionary::generate(&p).unwrap();
    assert!(dict.len() >= 8, "{}", dict.len());
    for (index, &code) in dict.codes().iter().enumerate() {
        let m = render_marker(family, code, &RenderOptions::default()).unwrap();
        for j in 0..4 {
            let d = decode(
                &m.view(),
                &shifted(&m.corners(), j),
                &dict,
                &DecodeParams::default(),
            )
            .unwrap();
            assert_eq!((d.index, d.rotation as usize), (index, (4 - j) % 4));
            assert_eq!(d.corners, m.corners());
        }
    }
}

#[test]
fn counter_clockwise_corners_are_rejected() {
    let dict = Dictionary::paper();
    let m = render_marker(dict.family(), dict.codes()[0], &RenderOptions::default()).unwrap();
    let c = m.corners();
    let mirrored = [c[1], c[0], c[3], c[2]];
    assert_eq!(
        decode(&m.view(), &mirrored, dict, &DecodeParams::default()),
        Err(Rejection::CounterClockwise)
    );
}

#[test]
fn a_white_quad_is_not_a_marker() {
    let dict = Dictionary::paper();
    let img = vec![255u8; 200 * 200];
    let view = GrayView::new(&img, 200, 200).unwrap();
    let c = [
        Point2::new(50.0, 50.0),
        Point2::new(150.0, 50.0),
        Point2::new(150.0, 150.0),
        Point2::new(50.0, 150.0),
    ];
    assert!(matches!(
        decode(&view, &c, dict, &DecodeParams::default()),
        Err(Rejection::LowContrast { .. })
    ));
}

#[test]
fn inverted_marker_border_is_not_dark() {
    let dict = Dictionary::paper();
    let m = render_marker(dict.family(), dict.codes()[3], &RenderOptions::default()).unwrap();
    let inv: Vec<u8> = m.pixels().iter().map(|&v| 255 - v).collect();
    let view = GrayView::new(&inv, m.width(), m.height()).unwrap();
    assert!(matches!(
        decode(&view, &m.corners(), dict, &DecodeParams::default()),
        Err(Rejection::LowContrast { .. } | Rejection::BorderNotDark { .. })
    ));
}

#[test]
fn marker_partly_outside_the_image_is_rejected_not_misread() {
    let dict = Dictionary::paper();
    let m = render_marker(dict.family(), dict.codes()[5], &RenderOptions::default()).unwrap();
    // Corners shifted left by 3 cells: the left border lies outside the image.
    let c = m.corners().map(|p| Point2::new(p.x - 60.0, p.y));
    assert_eq!(
        decode(&m.view(), &c, dict, &DecodeParams::default()),
        Err(Rejection::OutsideImage)
    );
}

#[test]
fn non_finite_corners_are_rejected() {
    let dict = Dictionary::paper();
    let m = render_marker(dict.family(), dict.codes()[0], &RenderOptions::default()).unwrap();
    let mut c = m.corners();
    c[2].x = f64::NAN;
    assert!(matches!(
        decode(&m.view(), &c, dict, &DecodeParams::default()),
        Err(Rejection::BadQuad { .. })
    ));
}

/// Renders `code` with the data cells of `flips` inverted.
fn render_flipped(dict: &Dictionary, code: u64, flips: &[usize]) -> fiducial::RenderedMarker {
    let read = flips.iter().fold(code, |c, &k| c ^ (1 << k));
    render_marker(
        dict.family(),
        read,
        &RenderOptions {
            px_per_cell: 8,
            quiet_cells: 1,
        },
    )
    .expect("valid code and options")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn up_to_two_flipped_cells_are_corrected(
        index in 0usize..100,
        flips in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 0..=2),
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let index = index % dict.len();
        let code = dict.codes()[index];
        let m = render_flipped(dict, code, &flips);
        let d = decode(&m.view(), &shifted(&m.corners(), shift), dict, &DecodeParams::default())
            .unwrap();
        prop_assert_eq!(d.index, index);
        prop_assert_eq!(d.distance as usize, flips.len());
        prop_assert_eq!(d.corners, m.corners());
    }

    /// Whatever pattern is shown, an accepted read is within 2 bits of the entry turned by
    /// the reported rotation.
    #[test]
    fn accepted_reads_are_close_to_the_turned_entry(code in 0u64..(1 << 20), shift in 0usize..4) {
        let dict = Dictionary::paper();
        let f = dict.family();
        let m = render_marker(f, code, &RenderOptions { px_per_cell: 6, quiet_cells: 1 }).unwrap();
        if let Ok(d) = decode(&m.view(), &shifted(&m.corners(), shift), dict, &DecodeParams::default()) {
            prop_assert!(d.distance * 2 < dict.min_distance());
            // The corners were given shifted, so the marker turned by `rotation` relative to
            // them is the rendered pattern turned back by the shift.
            let turn = (d.rotation as usize + shift) % 4;
            prop_assert_eq!(hamming(code, f.rotate(d.code, turn as u8).unwrap()), d.distance);
            // The entry's own NW corner is the rendered pattern's corner `turn`.
            prop_assert_eq!(d.corners, shifted(&m.corners(), turn));
        }
    }

    #[test]
    fn three_flipped_cells_never_give_a_wrong_id(
        index in 0usize..100,
        flips in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 3),
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let index = index % dict.len();
        let m = render_flipped(dict, dict.codes()[index], &flips);
        match decode(&m.view(), &shifted(&m.corners(), shift), dict, &DecodeParams::default()) {
            Ok(d) => prop_assert!(false, "3 flips read as entry {} (true {index})", d.index),
            Err(Rejection::NoMatch { nearest, .. }) => prop_assert!(nearest >= 3),
            Err(e) => prop_assert!(false, "unexpected rejection {e}"),
        }
    }
}

/// The detector's decoding: soft decisions only (2 weak cells, margin < 0.3), no hard
/// correction.
fn soft_params() -> DecodeParams {
    fiducial::DetectorConfig::default().decode
}

/// Renders entry `code` (8 px per cell, 1 quiet cell) with data cell `k` painted at
/// `levels[k]` where given (black 0, white 255, threshold 127.5).
fn render_levels(
    dict: &Dictionary,
    code: u64,
    levels: &[(usize, u8)],
) -> (Vec<u8>, fiducial::Corners, usize, usize) {
    let m = render_marker(
        dict.family(),
        code,
        &RenderOptions {
            px_per_cell: 8,
            quiet_cells: 1,
        },
    )
    .expect("valid code and options");
    let (w, h) = (m.width(), m.height());
    let mut px = m.pixels().to_vec();
    let n = dict.family().cols() as usize;
    for &(k, level) in levels {
        let (r, c) = (k / n, k % n);
        for y in (r + 2) * 8..(r + 3) * 8 {
            for x in (c + 2) * 8..(c + 3) * 8 {
                px[y * w + x] = level;
            }
        }
    }
    (px, m.corners(), w, h)
}

/// The level of a cell of `code` moved across the threshold to margin `margin` (0..1).
fn wrong_side(code: u64, k: usize, margin: f64) -> u8 {
    let black = code & (1 << k) != 0;
    let offset = margin * 127.5;
    // A black cell read light, a white one read dark.
    (if black {
        127.5 + offset
    } else {
        127.5 - offset
    })
    .round() as u8
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Up to two cells that read wrong by a small margin are flipped back by the soft
    /// decision, reporting their count as the distance.
    #[test]
    fn soft_decision_corrects_up_to_two_weak_cells(
        index in 0usize..100,
        flips in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 1..=2),
        margin in 0.03f64..0.25,
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let code = dict.codes()[index % dict.len()];
        let levels: Vec<(usize, u8)> = flips.iter().map(|&k| (k, wrong_side(code, k, margin))).collect();
        let (px, c, w, h) = render_levels(dict, code, &levels);
        let view = GrayView::new(&px, w, h).unwrap();
        let d = decode(&view, &shifted(&c, shift), dict, &soft_params()).unwrap();
        prop_assert_eq!(d.index, index % dict.len());
        prop_assert_eq!(d.distance as usize, flips.len());
        prop_assert_eq!(d.corners, c);
        // Without soft decisions (and without hard correction) the same view is rejected.
        let hard0 = DecodeParams { soft_errors: 0, ..soft_params() };
        let rejected = matches!(
            decode(&view, &shifted(&c, shift), dict, &hard0),
            Err(Rejection::NoMatch { .. })
        );
        prop_assert!(rejected);
    }

    /// A wrong cell read with a clear margin is never corrected by the soft decision, even
    /// next to a weak one: one clearly wrong cell (plus up to one weak cell) is rejected,
    /// and so are three weak cells.
    #[test]
    fn soft_decision_never_flips_confident_cells_or_three_weak_ones(
        index in 0usize..100,
        cells in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 3),
        strong in 0.4f64..1.0,
        weak in 0.03f64..0.25,
        case in 0usize..3,
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let code = dict.codes()[index % dict.len()];
        let levels: Vec<(usize, u8)> = match case {
            0 => vec![(cells[0], wrong_side(code, cells[0], strong))],
            1 => vec![
                (cells[0], wrong_side(code, cells[0], strong)),
                (cells[1], wrong_side(code, cells[1], weak)),
            ],
            _ => cells.iter().map(|&k| (k, wrong_side(code, k, weak))).collect(),
        };
        let (px, c, w, h) = render_levels(dict, code, &levels);
        let view = GrayView::new(&px, w, h).unwrap();
        let r = decode(&view, &shifted(&c, shift), dict, &soft_params());
        prop_assert!(matches!(r, Err(Rejection::NoMatch { .. })), "read {:?}", r);
    }

    /// Whatever grey levels the cells have, a soft-decision read is within
    /// `(d_min - 1) / 2` bits of the turned entry, and exactly `distance` bits from the
    /// thresholded cells.
    #[test]
    fn soft_reads_stay_within_half_the_minimum_distance(
        index in 0usize..100,
        levels in prop::array::uniform20(any::<u8>()),
        mostly in any::<u64>(),
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let f = dict.family();
        let code = dict.codes()[index % dict.len()];
        // Keep most cells at the entry's clean levels so that reads are often accepted.
        let painted: Vec<(usize, u8)> = (0..20)
            .filter(|k| mostly & (0b111 << (3 * (k % 20))) == 0)
            .map(|k| (k, levels[k]))
            .collect();
        let (px, c, w, h) = render_levels(dict, code, &painted);
        let shown = painted.iter().fold(code, |acc, &(k, v)| {
            if v < 128 { acc | (1 << k) } else { acc & !(1 << k) }
        });
        let view = GrayView::new(&px, w, h).unwrap();
        if let Ok(d) = decode(&view, &shifted(&c, shift), dict, &soft_params()) {
            prop_assert!(d.distance * 2 < dict.min_distance());
            let turn = (d.rotation as usize + shift) % 4;
            prop_assert_eq!(hamming(shown, f.rotate(d.code, turn as u8).unwrap()), d.distance);
        }
    }
}
