//! The demo's robot pair driven from outside: the follower's camera rendered at every step,
//! and the follower moved by whatever command it is given (for instance a ROS 2 `cmd_vel`
//! from a node in another process), through the scenario's imperfect actuation.
//!
//! The leader drives the scenario's inputs. Each step renders exactly what the demo renders
//! for the same poses: the same scene, noise seeds, motion blur, lighting and occlusion.
//! [`RobotPair::advance`] applies a command the way the demo applies its own controller's,
//! through the same actuation and odometry noise. A run in which the outside command equals
//! the demo's therefore reproduces the demo's frames.

use image::GrayImage;
use rand_chacha::ChaCha8Rng;
use unicycle::{ControllerConfig, Formation, Inputs, PlanarPose};

use crate::demo::{
    DemoConfig, DemoError, StepContext, World, exposure_poses, follower_scene, start_poses,
    validate,
};
use crate::scenario::{actuation_rng, follower_motion};
use crate::scenario_file::ScenarioSpec;

/// A leader and a follower of a scenario, stepped by outside commands.
#[derive(Debug, Clone)]
pub struct RobotPair {
    config: DemoConfig,
    spec: ScenarioSpec,
    /// Leader then follower, now and one step earlier.
    poses: Vec<PlanarPose>,
    previous: Vec<PlanarPose>,
    /// Inputs that moved each robot over the last step, as executed.
    applied: Vec<Inputs>,
    /// The follower's odometry of its last step.
    odometry: Inputs,
    step: usize,
    steps: usize,
    rng: ChaCha8Rng,
}

impl RobotPair {
    /// The pair of `spec` at its start (`t = 0`), standing still.
    ///
    /// # Errors
    /// [`DemoError`] for a scenario the demo refuses.
    pub fn new(spec: &ScenarioSpec) -> Result<Self, DemoError> {
        let config = DemoConfig::from_scenario(spec);
        validate(&config)?;
        let poses = start_poses(&config);
        Ok(Self {
            steps: (config.duration / config.dt).round() as usize,
            rng: actuation_rng(config.render.seed),
            previous: poses.clone(),
            poses,
            applied: vec![Inputs::new(0.0, 0.0); 2],
            odometry: Inputs::new(0.0, 0.0),
            step: 0,
            spec: spec.clone(),
            config,
        })
    }

    /// The current step (0 at the start).
    pub fn step(&self) -> usize {
        self.step
    }

    /// The number of steps of the scenario (its duration over its frame period).
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// The current time, seconds.
    pub fn t(&self) -> f64 {
        self.step as f64 * self.config.dt
    }

    /// The frame period, seconds.
    pub fn dt(&self) -> f64 {
        self.config.dt
    }

    /// The demo's configuration of the scenario (camera, mount, rendering, occlusion).
    pub fn config(&self) -> &DemoConfig {
        &self.config
    }

    /// The leader's and the follower's poses.
    pub fn poses(&self) -> (PlanarPose, PlanarPose) {
        (self.poses[0], self.poses[1])
    }

    /// The true formation now.
    ///
    /// # Errors
    /// The robots at the same point.
    pub fn truth(&self) -> Result<Formation, DemoError> {
        Ok(Formation::from_poses(
            &self.poses[0],
            &self.poses[1],
            self.config.mount.offset,
        )?)
    }

    /// The follower's controller in the demo at `t`: holding the starting formation, with
    /// the scenario's set-point changes due by `t` applied.
    ///
    /// # Errors
    /// The robots start at the same point.
    pub fn controller_at(&self, t: f64) -> Result<ControllerConfig, DemoError> {
        let (l, f) = start_poses(&self.config)
            .split_first()
            .map(|(l, rest)| (*l, rest[0]))
            .ok_or(DemoError::Config {
                what: "robots",
                value: 0.0,
                expected: "2",
            })?;
        let mut goal =
            ControllerConfig::hold(&Formation::from_poses(&l, &f, self.config.mount.offset)?);
        let mut due: Vec<_> = self.spec.setpoints.iter().filter(|s| t >= s.at).collect();
        due.sort_by(|a, b| a.at.total_cmp(&b.at));
        for change in due {
            goal = goal.with_setpoints(change.l12, change.alpha12);
        }
        Ok(goal)
    }

    /// Whether the leader is hidden from the follower's camera now.
    pub fn occluded(&self) -> bool {
        self.config.occluded_at(self.t())
    }

    /// The follower's odometry over the last step (what its wheels report): the inputs a
    /// tracker is given with this step's frame.
    pub fn odometry(&self) -> Inputs {
        self.odometry
    }

    /// The follower's camera frame now, as the demo renders it.
    ///
    /// # Errors
    /// [`DemoError`] when the scene cannot be rendered.
    pub fn render(&self) -> Result<GrayImage, DemoError> {
        let world = World::new(&self.config)?;
        let odometry = [self.applied[0], self.odometry];
        let ctx = StepContext {
            step: self.step,
            t: self.t(),
            occluded: self.occluded(),
            poses: &self.poses,
            previous: &self.previous,
            applied: &self.applied,
            odometry: &odometry,
        };
        let specs: Vec<_> = exposure_poses(&self.config, &ctx)?
            .iter()
            .map(|poses| follower_scene(&world, &ctx, poses, 1))
            .collect();
        let gradient = self.config.gradient.map(|g| synthcam::Gradient {
            from: g.from,
            to: g.to,
            angle: g.angle_deg.to_radians(),
        });
        Ok(crate::scene::render_scene_exposure(&specs, gradient, &world.rig, world.dict)?.image)
    }

    /// Moves both robots one step: the leader by the scenario's inputs, the follower by
    /// `command` through the scenario's actuation (its odometry noised as the scenario
    /// says). Returns the inputs the follower's wheels executed.
    ///
    /// # Errors
    /// [`DemoError::Config`] for a non-finite command; past the last step, nothing moves.
    pub fn advance(&mut self, command: Inputs) -> Result<Inputs, DemoError> {
        if !(command.v.is_finite() && command.w.is_finite()) {
            return Err(DemoError::Config {
                what: "follower command",
                value: if command.v.is_finite() {
                    command.w
                } else {
                    command.v
                },
                expected: "finite v (m/s) and w (rad/s)",
            });
        }
        let leader = self.spec.leader_inputs(self.t());
        let (executed, odometry) = follower_motion(
            &self.spec.actuation,
            self.spec.odometry_noise_std,
            command,
            &mut self.rng,
        );
        self.odometry = odometry;
        if self.step < self.steps {
            self.previous.clone_from(&self.poses);
            self.poses[0] = self.poses[0].integrate_exact(leader, self.config.dt)?;
            self.poses[1] = self.poses[1].integrate_exact(executed, self.config.dt)?;
            self.applied = vec![leader, executed];
            self.step += 1;
        }
        Ok(executed)
    }
}
