//! Annotation: the rig drawn from the true pose lies on the rendered markers, labels are
//! drawn, and poses behind the camera draw nothing rather than garbage.

use fiducial::Dictionary;
use formation_sim::annotate::{MarkerLabel, RigOverlay, annotate};
use formation_sim::paper::paper_scene;
use formation_sim::scene::render_scene;
use formation_tracker::rig::RigModel;
use nalgebra::{Matrix3, Point2};

#[test]
fn true_rig_is_drawn_on_the_markers() {
    let rig = RigModel::reference();
    let out = render_scene(&paper_scene(10).unwrap(), &rig, Dictionary::paper()).unwrap();
    let k = pose::Intrinsics::from_matrix(&Matrix3::from_row_slice(&out.truth.k.concat())).unwrap();
    let camera = pose::Camera::pinhole(k, out.image.width(), out.image.height());
    let overlays: Vec<RigOverlay> = out
        .truth
        .robots
        .iter()
        .map(|r| RigOverlay {
            robot: r.robot,
            rotation: r.rotation,
            translation: r.translation,
        })
        .collect();
    let img = annotate(&out.image, &camera, &rig, &[], &overlays).unwrap();
    img.save(std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("annotate-fig10.png"))
        .unwrap();
    // On every readable face, the drawn marker border passes through its true corners:
    // a pixel near the middle of the top edge is coloured (not grey).
    let mut checked = 0;
    for r in &out.truth.robots {
        for f in r.faces.iter().filter(|f| f.readable) {
            let c = f.corners_px.unwrap();
            let (x, y) = ((c[0][0] + c[1][0]) / 2.0, (c[0][1] + c[1][1]) / 2.0);
            // Within a pixel of it (the line rasteriser truncates).
            let hit = (-1i32..=1).any(|dy| {
                (-1i32..=1).any(|dx| {
                    let p = img
                        .get_pixel(
                            (x.round() as i32 + dx) as u32,
                            (y.round() as i32 + dy) as u32,
                        )
                        .0;
                    p[0] != p[1] || p[1] != p[2]
                })
            });
            assert!(hit, "robot {} face {}", r.robot, f.face);
            checked += 1;
        }
    }
    assert!(checked >= 4);
    // Away from the robots the image is untouched grey.
    let p = img.get_pixel(5, 5).0;
    assert_eq!((p[0], p[0]), (p[1], p[2]));
    assert_eq!(p[0], out.image.get_pixel(5, 5).0[0]);
}

#[test]
fn labels_are_drawn_and_poses_behind_the_camera_are_skipped() {
    let rig = RigModel::reference();
    let grey = image::GrayImage::from_pixel(200, 150, image::Luma([128]));
    let k = pose::Intrinsics::square_pixels(200.0, 200.0, 99.5, 74.5).unwrap();
    let camera = pose::Camera::pinhole(k, 200, 150);
    let marker = MarkerLabel {
        robot: 2,
        face: 3,
        corners: [
            Point2::new(60.0, 60.0),
            Point2::new(120.0, 60.0),
            Point2::new(120.0, 110.0),
            Point2::new(60.0, 110.0),
        ],
    };
    let behind = RigOverlay {
        robot: 1,
        rotation: [0.0, 0.0, 0.0],
        translation: [0.0, 0.0, -3.0],
    };
    let img = annotate(&grey, &camera, &rig, &[marker], &[behind]).unwrap();
    let coloured = |x0: u32, x1: u32, y0: u32, y1: u32| {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let p = img.get_pixel(x, y).0;
                p != [128, 128, 128]
            })
            .count()
    };
    // The outline, and the label text above it.
    assert!(coloured(55, 125, 55, 115) > 200);
    assert!(coloured(55, 100, 40, 58) > 10, "label");
    // Nothing else was drawn (the rig behind the camera is skipped).
    assert_eq!(coloured(0, 200, 120, 150), 0);
    assert_eq!(coloured(130, 200, 0, 150), 0);
}
