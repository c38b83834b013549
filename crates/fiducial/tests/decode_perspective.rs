//! Decoding markers seen in perspective (anti-aliased synthetic views), with sub-pixel
//! corners, noise and low contrast.

use fiducial::{Corners, DecodeParams, Dictionary, GrayView, Rejection, decode};
use nalgebra::{Matrix3, Point2, SMatrix, SVector, Vector3};
use proptest::prelude::*;

/// Homography taking `src[i]` to `dst[i]` (h33 = 1).
fn homography(src: &[Point2<f64>; 4], dst: &[Point2<f64>; 4]) -> Matrix3<f64> {
    let mut a = SMatrix::<f64, 8, 8>::zeros();
    let mut rhs = SVector::<f64, 8>::zeros();
    for i in 0..4 {
        let (x, y, u, v) = (src[i].x, src[i].y, dst[i].x, dst[i].y);
        a.row_mut(2 * i)
            .copy_from_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]);
        a.row_mut(2 * i + 1)
            .copy_from_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]);
        rhs[2 * i] = u;
        rhs[2 * i + 1] = v;
    }
    let h = a.full_piv_lu().solve(&rhs).expect("general position");
    Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0)
}

/// A `w x h` view of marker `code` (4 x 5) whose outer border corners land on `corners`
/// (NW, NE, SE, SW of the marker), 4 x 4 supersampled; `dark`/`light` grey levels; the
/// background beyond a 1.5-cell quiet zone is mid grey; deterministic noise of amplitude
/// `noise`.
fn view_of(
    code: u64,
    corners: &Corners,
    w: usize,
    h: usize,
    dark: f64,
    light: f64,
    noise: f64,
) -> Vec<u8> {
    let marker = [
        Point2::new(0.0, 0.0),
        Point2::new(7.0, 0.0),
        Point2::new(7.0, 6.0),
        Point2::new(0.0, 6.0),
    ];
    let inv = homography(corners, &marker);
    let mut seed = 0x2545_F491_4F6C_DD1Du64 ^ code;
    let mut out = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let p = inv
                        * Vector3::new(
                            x as f64 - 0.375 + 0.25 * f64::from(sx),
                            y as f64 - 0.375 + 0.25 * f64::from(sy),
                            1.0,
                        );
                    let (u, v) = (p.x / p.z, p.y / p.z);
                    let level = if (0.0..7.0).contains(&u) && (0.0..6.0).contains(&v) {
                        let (cu, cv) = (u as u32, v as u32);
                        let black = cu == 0
                            || cv == 0
                            || cu == 6
                            || cv == 5
                            || (code >> ((cv - 1) * 5 + (cu - 1))) & 1 == 1;
                        if black { dark } else { light }
                    } else if (-1.5..8.5).contains(&u) && (-1.5..7.5).contains(&v) {
                        light
                    } else {
                        0.5 * (dark + light)
                    };
                    acc += level;
                }
            }
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let n = ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * noise;
            out[y * w + x] = (acc / 16.0 + n).round().clamp(0.0, 255.0) as u8;
        }
    }
    out
}

/// A perspective quad: a rectangle of aspect 7:6 of size `s`, turned by `angle`, each
/// corner jittered by up to `jitter` of the size.
fn quad(cx: f64, cy: f64, s: f64, angle: f64, jitter: [(f64, f64); 4]) -> Corners {
    let (c, sn) = (angle.cos(), angle.sin());
    let base = [(-3.5, -3.0), (3.5, -3.0), (3.5, 3.0), (-3.5, 3.0)];
    core::array::from_fn(|i| {
        let (x, y) = (base[i].0 * s / 7.0, base[i].1 * s / 7.0);
        Point2::new(
            cx + c * x - sn * y + jitter[i].0 * s,
            cy + sn * x + c * y + jitter[i].1 * s,
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn perspective_views_decode_with_the_right_orientation(
        index in 0usize..100,
        size in 40.0..140.0f64,
        angle in -3.2..3.2f64,
        jitter in prop::array::uniform4((-0.08..0.08f64, -0.08..0.08f64)),
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let index = index % dict.len();
        let code = dict.codes()[index];
        let corners = quad(100.0, 100.0, size, angle, jitter);
        let img = view_of(code, &corners, 200, 200, 30.0, 220.0, 6.0);
        let view = GrayView::new(&img, 200, 200).unwrap();
        // The detector hands corners clockwise in the image from any start.
        let given: Corners = core::array::from_fn(|i| corners[(i + shift) % 4]);
        let d = decode(&view, &given, dict, &DecodeParams::default())
            .map_err(|e| TestCaseError::fail(format!("{e}")))?;
        prop_assert_eq!(d.index, index);
        prop_assert_eq!(d.distance, 0);
        prop_assert_eq!(d.rotation as usize, (4 - shift) % 4);
        prop_assert_eq!(d.corners, corners);
        prop_assert!(d.contrast > 150.0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Small, noisy, perspective views (3..20 pixels per cell) of a marker with three
    /// flipped cells are rejected, never read as an entry.
    #[test]
    fn three_flips_in_perspective_are_rejected(
        index in 0usize..100,
        flips in proptest::sample::subsequence((0..20).collect::<Vec<usize>>(), 3),
        size in 21.0..140.0f64,
        angle in -3.2..3.2f64,
        jitter in prop::array::uniform4((-0.08..0.08f64, -0.08..0.08f64)),
        shift in 0usize..4,
    ) {
        let dict = Dictionary::paper();
        let code = flips.iter().fold(dict.codes()[index % dict.len()], |c, &k| c ^ (1 << k));
        let corners = quad(100.0, 100.0, size, angle, jitter);
        let img = view_of(code, &corners, 200, 200, 30.0, 220.0, 6.0);
        let view = GrayView::new(&img, 200, 200).unwrap();
        let given: Corners = core::array::from_fn(|i| corners[(i + shift) % 4]);
        let got = decode(&view, &given, dict, &DecodeParams::default());
        prop_assert!(got.is_err(), "3 flips of entry {} read as {:?}", index % dict.len(), got);
    }
}

#[test]
fn low_contrast_is_rejected_at_the_set_minimum() {
    let dict = Dictionary::paper();
    let corners = quad(60.0, 60.0, 80.0, 0.3, [(0.0, 0.0); 4]);
    let img = view_of(dict.codes()[1], &corners, 120, 120, 100.0, 115.0, 0.0);
    let view = GrayView::new(&img, 120, 120).unwrap();
    let strict = DecodeParams::default();
    assert!(matches!(
        decode(&view, &corners, dict, &strict),
        Err(Rejection::LowContrast { .. })
    ));
    // With the minimum lowered, the faint marker reads.
    let lenient = DecodeParams {
        min_contrast: 8.0,
        ..strict
    };
    assert_eq!(decode(&view, &corners, dict, &lenient).unwrap().index, 1);
}

#[test]
fn slightly_wrong_corners_still_decode() {
    let dict = Dictionary::paper();
    let corners = quad(
        80.0,
        80.0,
        100.0,
        0.1,
        [(0.02, 0.0), (0.0, 0.03), (-0.02, 0.0), (0.0, -0.02)],
    );
    let img = view_of(dict.codes()[7], &corners, 160, 160, 20.0, 230.0, 10.0);
    let view = GrayView::new(&img, 160, 160).unwrap();
    // Every corner off by about a pixel.
    let off = [(-1.0, 0.7), (0.8, -1.0), (1.1, 0.9), (-0.6, 1.0)];
    let noisy: Corners =
        core::array::from_fn(|i| corners[i] + nalgebra::Vector2::new(off[i].0, off[i].1));
    assert_eq!(
        decode(&view, &noisy, dict, &DecodeParams::default())
            .unwrap()
            .index,
        7
    );
}
