//! Render two leader robots carrying octagon rigs of simple cell-grid markers, write the image
//! as PGM and print the ground truth.
//!
//! Run with `cargo run -p formation-synthcam --example two_robots [-- OUT.pgm]`
//! (default output: `target/synthcam_two_robots.pgm`).

use std::sync::Arc;

#[path = "../tests/common/mod.rs"]
mod common;

use synthcam::{
    Body, CellGrid, Face, Gradient, Ground, RenderSettings, Robot, Scene, SoftChecker, SynthError,
    render,
};
use unicycle::PlanarPose;

/// A marker-like cell grid: one-cell white quiet zone, one-cell black border, 4 x 5 data cells
/// taken from the bits of `code` (bit k at row k / 5, column k % 5; 1 = black). 8 rows x 9 cols,
/// so with 20 mm cells it is 160 mm x 180 mm: exactly a reference face.
fn marker(code: u32) -> Result<CellGrid, SynthError> {
    let (rows, cols) = (8, 9);
    let mut black = vec![false; rows * cols];
    for r in 1..rows - 1 {
        for c in 1..cols - 1 {
            let border = r == 1 || r == rows - 2 || c == 1 || c == cols - 2;
            black[r * cols + c] = border || (code >> ((r - 2) * 5 + (c - 2))) & 1 == 1;
        }
    }
    CellGrid::from_bits(rows, cols, &black)
}

fn robot(pose: PlanarPose, first_code: u32) -> Result<Robot, SynthError> {
    let mut r = Robot::new(
        pose,
        Body::Cylinder {
            radius: 0.2,
            height: 0.2,
            albedo: 0.35,
        },
    );
    for (i, placement) in common::octagon_faces(0.16)?.into_iter().enumerate() {
        let code = first_code
            .wrapping_mul(2_654_435_761)
            .rotate_left(i as u32 * 5)
            & 0xFFFFF;
        r = r.with_face(Face::new(i as u32 + 1, placement, Arc::new(marker(code)?)));
    }
    Ok(r)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "target/synthcam_two_robots.pgm".to_string());

    let mut scene = Scene::new(0.85);
    scene.ground = Some(Ground {
        texture: Arc::new(SoftChecker::new(0.42, 0.58)?),
        tile: 1.0,
    });
    // Leader A ahead and to the left, turned a little left; leader B ahead and to the right.
    scene
        .robots
        .push(robot(PlanarPose::new(1.6, 0.45, 0.5), 1)?);
    scene
        .robots
        .push(robot(PlanarPose::new(2.2, -0.5, -0.4), 7)?);

    // The follower's camera: 10 cm ahead of its reference point, 30 cm high, level.
    let mount = common::mount(0.1, 0.3, 0.0, 0.0);
    let camera = common::camera(640, 480, 60.0, &mount, PlanarPose::new(0.0, 0.0, 0.0))?;

    let settings = RenderSettings {
        supersampling: 2,
        gradient: Some(Gradient {
            from: 1.0,
            to: 0.75,
            angle: 0.0,
        }),
        blur_sigma: 0.5,
        noise_sigma: 2.0,
        seed: 42,
        ..RenderSettings::default()
    };
    let rendered = render(&scene, &camera, &settings)?;
    let file = std::fs::File::create(&out)?;
    rendered.frame.write_pnm(std::io::BufWriter::new(file))?;
    println!(
        "wrote {out} ({} x {})",
        rendered.frame.width, rendered.frame.height
    );

    for r in &rendered.truth.robots {
        let t = r.body_to_camera.translation.vector;
        let (roll, pitch, yaw) = r.body_to_camera.rotation.euler_angles();
        println!(
            "robot {} at world ({:.2}, {:.2}, {:.1} deg): camera-frame t = ({:.3}, {:.3}, {:.3}) m, rpy = ({:.1}, {:.1}, {:.1}) deg",
            r.index,
            r.pose.x,
            r.pose.y,
            r.pose.theta.to_degrees(),
            t.x,
            t.y,
            t.z,
            roll.to_degrees(),
            pitch.to_degrees(),
            yaw.to_degrees()
        );
        for f in &r.faces {
            let corners = f.corners_px.map_or_else(
                || "behind camera".to_string(),
                |c| {
                    c.iter()
                        .map(|p| format!("({:.2}, {:.2})", p.x, p.y))
                        .collect::<Vec<_>>()
                        .join(" ")
                },
            );
            println!(
                "  face {}: visible {:5}  off-axis {:6.1} deg  width {:6.1} px  NW NE SE SW {}",
                f.label,
                f.visible,
                f.off_axis_deg,
                f.width_px.unwrap_or(f64::NAN),
                corners
            );
        }
    }
    Ok(())
}
