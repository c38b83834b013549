//! `RobotPair` renders what the demo renders: driven by the demo's own commands (its
//! controller on the true formation, open loop), its frames and odometry are the demo's.
#![allow(clippy::unwrap_used)] // tests may unwrap (house rules)

use std::path::Path;

use formation_sim::demo::{DemoConfig, DemoError, run_demo_until};
use formation_sim::pair::RobotPair;
use formation_sim::scenario_file::ScenarioSpec;
use unicycle::SeparationBearingController;

fn spec(name: &str) -> ScenarioSpec {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/scenarios")
        .join(name);
    ScenarioSpec::load(&path).unwrap()
}

/// The demo's first `steps` frames of robot 2 and the inputs handed with them.
fn demo_frames(spec: &ScenarioSpec, steps: usize) -> Vec<(image::GrayImage, unicycle::Inputs)> {
    let mut frames = Vec::new();
    let config = DemoConfig::from_scenario(spec);
    let stop = std::cell::Cell::new(false);
    let result = run_demo_until(
        &config,
        |_, _| {},
        |f| {
            if f.robot == 2 {
                frames.push((f.image.clone(), f.inputs));
            }
            if frames.len() >= steps {
                stop.set(true);
            }
        },
        || stop.get(),
    );
    assert!(
        matches!(result, Err(DemoError::Stopped { .. })),
        "{result:?}"
    );
    frames
}

#[test]
fn driven_like_the_demo_the_pair_renders_the_demos_frames() {
    // far.yaml: motion blur, a lighting gradient and imperfect actuation all in play.
    for name in ["reference.yaml", "far-actuation.yaml"] {
        let spec = spec(name);
        let steps = 6;
        let want = demo_frames(&spec, steps);
        let mut pair = RobotPair::new(&spec).unwrap();
        for (k, (image, inputs)) in want.iter().enumerate() {
            assert_eq!(pair.step(), k);
            let got = pair.render().unwrap();
            assert!(got == *image, "{name}: frame {k} differs from the demo's");
            if k > 0 {
                assert_eq!(pair.odometry(), *inputs, "{name}: odometry at frame {k}");
            }
            let law = SeparationBearingController::new(
                pair.config().mount.offset,
                pair.controller_at(pair.t()).unwrap(),
            )
            .unwrap();
            let command = law
                .inputs(&pair.truth().unwrap(), spec.leader_inputs(pair.t()))
                .unwrap();
            pair.advance(command).unwrap();
        }
        // The follower moved: the comparison covered motion, not a standing start.
        let (_, follower) = pair.poses();
        let start = RobotPair::new(&spec).unwrap().poses().1;
        assert!(
            (follower.x - start.x).abs() > 1e-3,
            "{name}: the follower did not move"
        );
    }
}

#[test]
fn a_non_finite_command_is_refused() {
    let mut pair = RobotPair::new(&spec("reference.yaml")).unwrap();
    let err = pair
        .advance(unicycle::Inputs::new(f64::NAN, 0.0))
        .unwrap_err();
    assert!(err.to_string().contains("follower command"), "{err}");
    assert_eq!(pair.step(), 0);
}
