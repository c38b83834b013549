//! Prints what a running `formation-tracker ros2` node publishes for one leader: its
//! formation variables with their standard deviations, decoded from the documented
//! `Float64MultiArray` layout. `ros2 topic echo` shows the same without any of our code.
//!
//! ```text
//! ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST cargo run -p formation-ros2 --example echo_formation -- 1 10
//! ```
//! Arguments: the leader's robot id (default 1) and how many seconds to listen (default 10).

use std::time::{Duration, Instant};

use formation_ros2::topics::{sensor_data, subscription};
use formation_ros2::{RosEnv, msg};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let robot: u32 = args.next().map_or(Ok(1), |a| a.parse())?;
    let seconds: f64 = args.next().map_or(Ok(10.0), |a| a.parse())?;
    let mut node = RosEnv::from_env()?.node("/", "echo_formation")?;
    let topic = format!("formation/leader_{robot}/formation");
    let sub = subscription::<msg::Float64MultiArray>(&mut node, &topic, &sensor_data(10))?;
    println!("listening on {topic} for {seconds} s");
    let end = Instant::now() + Duration::from_secs_f64(seconds);
    let mut seen = 0;
    while Instant::now() < end {
        match sub.take() {
            Ok(Some((m, _))) if m.data.len() == 35 => {
                let d = &m.data;
                // Row 0: stamp, robot, status, since seen, l12_std; row 1: the estimate;
                // rows 2-6: the covariance (its diagonal at 10 + 6 i).
                println!(
                    "t {:.3} robot {} status {} l12 {:.3} +- {:.3} m, alpha12 {:.3} +- {:.3} rad, beta12 {:.3} rad, v1 {:.2} m/s, w1 {:.2} rad/s",
                    d[0],
                    d[1],
                    d[2],
                    d[5],
                    d[10].sqrt(),
                    d[6],
                    d[16].sqrt(),
                    d[7],
                    d[8],
                    d[9]
                );
                seen += 1;
            }
            Ok(Some((m, _))) => eprintln!("unexpected layout: {} values", m.data.len()),
            Ok(None) => std::thread::sleep(Duration::from_millis(5)),
            Err(e) => eprintln!("unreadable message: {e:?}"),
        }
    }
    println!("{seen} messages");
    Ok(())
}
