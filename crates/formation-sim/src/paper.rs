//! The paper's scenes (spec section 6, Figs. 7-11) and seeded random scenes.
//!
//! The paper places two leaders relative to the camera-carrying robot (at the origin,
//! heading 0). It does not give its image size, field of view, marker size or camera
//! offset; we fix them: 640 x 480, horizontal field of view 60 degrees, the camera level at
//! marker height (0.30 m) with no offset ahead of the robot's reference point
//! ([`crate::scene::paper_mount`]), the reference rig, sensor noise sigma 3 grey levels and
//! blur sigma 1 px, 8 x 8 samples per pixel (see [`RenderSpec`]), and the figure number as
//! the noise seed.

use std::f64::consts::FRAC_PI_2;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::scene::{CameraSpec, RenderSpec, RobotSpec, SceneError, SceneSpec, paper_mount};

/// One of the paper's configurations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperFigure {
    /// Figure number (7..=11).
    pub fig: u8,
    /// Leader 1 (robot 1): `[x, y, theta]`.
    pub q1: [f64; 3],
    /// Leader 2 (robot 2): `[x, y, theta]`.
    pub q2: [f64; 3],
    /// Faces the paper reports read for robots 1 and 2 (Figs. 7-9 only).
    pub paper_faces: Option<(&'static [u8], &'static [u8])>,
}

/// Figs. 7-11 (spec section 6).
pub const PAPER_FIGURES: [PaperFigure; 5] = [
    PaperFigure {
        fig: 7,
        q1: [1.5, 0.25, 0.0],
        q2: [2.0, -0.45, 0.0],
        paper_faces: Some((&[2, 3, 4, 5], &[1, 2, 3])),
    },
    PaperFigure {
        fig: 8,
        q1: [2.5, -0.5, 0.0],
        q2: [3.5, 0.5, 0.0],
        paper_faces: Some((&[2, 3, 4], &[2, 3, 4])),
    },
    PaperFigure {
        fig: 9,
        q1: [2.5, -0.5, 0.0],
        q2: [3.5, 0.5, FRAC_PI_2],
        paper_faces: Some((&[2, 3, 4], &[1, 2])),
    },
    PaperFigure {
        fig: 10,
        q1: [2.5, -0.5, 0.0],
        q2: [3.0, 0.25, 0.0],
        paper_faces: None,
    },
    PaperFigure {
        fig: 11,
        q1: [1.5, -0.5, 0.0],
        q2: [3.5, 0.5, -FRAC_PI_2],
        paper_faces: None,
    },
];

/// The configuration of figure `fig`.
pub fn paper_figure(fig: u8) -> Result<&'static PaperFigure, SceneError> {
    PAPER_FIGURES
        .iter()
        .find(|f| f.fig == fig)
        .ok_or_else(|| SceneError::Field {
            field: "--paper-fig".into(),
            reason: format!("the paper's scenes are Figs. 7 to 11, got {fig}"),
        })
}

/// The scene of figure `fig` (7..=11).
pub fn paper_scene(fig: u8) -> Result<SceneSpec, SceneError> {
    let f = paper_figure(fig)?;
    let robot = |robot: u32, q: [f64; 3]| RobotSpec {
        robot,
        x: q[0],
        y: q[1],
        theta: q[2],
    };
    Ok(SceneSpec {
        name: format!("fig{fig}"),
        camera_robot: Default::default(),
        mount: paper_mount(),
        camera: CameraSpec::default(),
        render: RenderSpec {
            seed: u64::from(fig),
            ..RenderSpec::default()
        },
        robots: vec![robot(1, f.q1), robot(2, f.q2)],
    })
}

/// Smallest distance between two leaders' reference points in a random scene, metres
/// (two reference rigs need about 0.47 m).
pub const MIN_SEPARATION_M: f64 = 0.6;

/// Random scene number `index` of the seeded series `seed`: one to three leaders (robots
/// 1..=3), each at a distance between 0.3 m and 3 m from the camera (to its reference
/// point), at a bearing inside the middle 80 % of the horizontal field of view, heading
/// within +-90 degrees of the camera's; leaders at least [`MIN_SEPARATION_M`] apart. The
/// paper's camera, mount and effects; noise seed `index`.
pub fn random_scene(seed: u64, index: u64) -> SceneSpec {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let camera = CameraSpec::default();
    let mount = paper_mount();
    let half_fov = (camera.hfov_deg / 2.0).to_radians() * 0.8;
    let n: u32 = rng.random_range(1..=3);
    let mut robots: Vec<RobotSpec> = Vec::new();
    let mut attempts = 0;
    while robots.len() < n as usize && attempts < 1000 {
        attempts += 1;
        let range: f64 = rng.random_range(0.3..=3.0);
        let bearing: f64 = rng.random_range(-half_fov..=half_fov);
        let theta: f64 = rng.random_range(-FRAC_PI_2..=FRAC_PI_2);
        let x = mount.offset + range * bearing.cos();
        let y = range * bearing.sin();
        if robots
            .iter()
            .all(|r| (r.x - x).hypot(r.y - y) >= MIN_SEPARATION_M)
        {
            robots.push(RobotSpec {
                robot: robots.len() as u32 + 1,
                x,
                y,
                theta,
            });
        }
    }
    SceneSpec {
        name: format!("random-{index}"),
        camera_robot: Default::default(),
        mount,
        camera,
        render: RenderSpec {
            seed: index,
            ..RenderSpec::default()
        },
        robots,
    }
}
