//! Lists the frames of an image folder or a y4m file: index, size and mean grey level.
//!
//! `cargo run -p formation-io --example read_frames -- DIR_OR_Y4M`; with no argument it reads
//! the marker images of `fixtures/markers/DICT_4X4_50`.

use std::path::PathBuf;

use formation_io::frames::FrameSource;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let input = std::env::args_os().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/markers/DICT_4X4_50"),
        PathBuf::from,
    );
    let mut source = FrameSource::open(&input)?;
    while let Some(frame) = source.next_frame()? {
        let image = frame.image;
        let mean = image.data.iter().map(|&p| f64::from(p)).sum::<f64>() / image.data.len() as f64;
        println!(
            "frame {:>4}: {} x {}, mean grey {mean:.1}",
            frame.index, image.width, image.height
        );
    }
    println!(
        "{} frames read from {}",
        source.frames_read(),
        input.display()
    );
    Ok(())
}
