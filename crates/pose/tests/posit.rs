//! POSIT on its own.

mod common;

use common::*;
use pose::{PoseError, posit};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn posit_is_close_on_three_faces() {
    let k = camera();
    let model = three_faces_model();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..50 {
        let truth = random_rig_pose(&mut rng);
        let image = project_all(&k, &truth, &model);
        let p = posit(&k, &model, &image).unwrap();
        // POSIT on exact data converges to the exact pose.
        assert!(
            p.rotation_angle_to(&truth) < 1e-6,
            "{}",
            p.rotation_angle_to(&truth)
        );
        assert!(translation_error(&p, &truth) < 1e-6);
    }
}

#[test]
fn posit_rejects_coplanar_points() {
    let k = camera();
    let model = face_model();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let image = project_all(&k, &random_face_pose(&mut rng, (1.0, 2.0), 0.5), &model);
    assert!(matches!(
        posit(&k, &model, &image),
        Err(PoseError::Degenerate { .. })
    ));
    assert!(matches!(
        posit(&k, &model[..3], &image[..3]),
        Err(PoseError::TooFewPoints { .. })
    ));
    assert!(matches!(
        posit(&k, &model, &image[..3]),
        Err(PoseError::LengthMismatch { .. })
    ));
}
