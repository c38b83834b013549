//! A frame of the demo's first robots and the leader's predicted region, shared by the
//! guided-detection tests and benchmarks: robot 2's camera (at the origin, heading 0)
//! looking at robot 1, rendered once (one sample per pixel, noise 3, blur 1), then three
//! tracked frames of it and the tracker's prediction for the next, projected as the
//! pipeline's guided mode does ([`leader_region`], default settings).

use fiducial::{Detector, DetectorConfig, Dictionary};
use formation_sim::scene::{self, CameraSpec, RenderSpec, RobotSpec, SceneSpec};
use formation_tracker::guided::{GuidedConfig, LeaderRegion, leader_region};
use formation_tracker::mount::CameraMount;
use formation_tracker::pipeline::Pipeline;
use formation_tracker::rig::RigModel;
use formation_tracker::robots::RobotConfig;
use formation_tracker::tracker::{Tracker, TrackerConfig};
use unicycle::{Inputs, PlanarPose};

/// Frame interval, s.
const DT: f64 = 1.0 / 30.0;

/// The `width x height` frame (60 deg horizontal field of view) of robot 1 at
/// `(x, y, theta)`, and its predicted region.
pub fn leader_frame(
    width: usize,
    height: usize,
    x: f64,
    y: f64,
    theta: f64,
) -> (Vec<u8>, LeaderRegion) {
    let camera = CameraSpec {
        width,
        height,
        hfov_deg: 60.0,
    };
    let mount = CameraMount::default();
    let rig = RigModel::reference();
    let dict = Dictionary::paper();
    let spec = SceneSpec {
        name: String::new(),
        camera_robot: PlanarPose::new(0.0, 0.0, 0.0),
        mount,
        camera,
        render: RenderSpec {
            supersampling: 1,
            noise_sigma: 3.0,
            blur_sigma: 1.0,
            seed: 1,
        },
        robots: vec![RobotSpec {
            robot: 1,
            x,
            y,
            theta,
        }],
    };
    let image = scene::render_scene(&spec, &rig, dict)
        .expect("the scene renders")
        .image
        .into_raw();
    let k = pose::Intrinsics::from_hfov(60f64.to_radians(), width as u32, height as u32)
        .expect("valid camera");
    let mut pipeline = Pipeline::new(
        Detector::with_dictionary(DetectorConfig::default(), dict.clone()),
        pose::PoseSolver::new(k),
        (width as u32, height as u32),
        rig.clone(),
        RobotConfig::default(),
        Tracker::new(TrackerConfig::reference(mount.offset, DT)).expect("reference tracker"),
    );
    let still = Inputs::new(0.0, 0.0);
    for i in 0..3 {
        pipeline
            .process(&image, width, height, i as f64 * DT, still, mount)
            .expect("the frame is processed");
    }
    let faces = rig.face_geometries().expect("reference rig");
    let predicted = pipeline.tracker().predict(3.0 * DT, still);
    assert_eq!(predicted.len(), 1, "one leader tracked and predicted");
    let region = leader_region(
        &predicted[0],
        &faces,
        &mount,
        &k,
        (width, height),
        &GuidedConfig::default(),
    )
    .expect("the leader's region is in the frame");
    (image, region)
}
