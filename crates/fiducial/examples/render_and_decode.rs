//! Render a marker of the paper's dictionary upside down with one cell flipped, decode it,
//! and print the entry, the bits corrected, the rotation and the marker's own corners.
//!
//! Run with `cargo run -p formation-fiducial --example render_and_decode [INDEX]`.

use fiducial::{DecodeParams, Dictionary, RenderOptions, decode, render_marker};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let index: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(0);
    let dict = Dictionary::paper();
    let family = dict.family();
    let code = dict
        .code(index)
        .ok_or_else(|| format!("the dictionary has {} codes", dict.len()))?;
    println!(
        "dictionary: {}x{} cells, d_min {}, {} codes; entry {index} = {code} ({code:#07x})",
        family.rows(),
        family.cols(),
        dict.min_distance(),
        dict.len()
    );

    // Render it upside down: the half-turned code is what a camera sees of a marker
    // mounted upside down.
    let upside_down = family.rotate(code, 2)?;
    let marker = render_marker(family, upside_down, &RenderOptions::default())?;
    let mut bits = [false; 64];
    for row in family
        .bits_of(upside_down, &mut bits)
        .chunks(family.cols() as usize)
    {
        let line: String = row.iter().map(|&b| if b { '#' } else { '.' }).collect();
        println!("  {line}");
    }

    // Flip one cell to show the correction.
    let mut pixels = marker.pixels().to_vec();
    let (w, k) = (marker.width(), 20);
    for y in 2 * k..3 * k {
        for x in 2 * k..3 * k {
            pixels[y * w + x] = 255 - pixels[y * w + x];
        }
    }
    let view = fiducial::GrayView::new(&pixels, w, marker.height())?;

    let found = decode(&view, &marker.corners(), dict, &DecodeParams::default())?;
    println!(
        "decoded: entry {} (code {}), {} bit(s) corrected, rotation {} quarter turn(s), \
         contrast {:.0}, confidence {:.2}",
        found.index, found.code, found.distance, found.rotation, found.contrast, found.confidence
    );
    println!("marker corners (NW, NE, SE, SW):");
    for p in found.corners {
        println!("  ({:.1}, {:.1})", p.x, p.y);
    }
    Ok(())
}
