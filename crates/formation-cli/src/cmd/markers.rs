//! `formation-tracker markers`: print-ready marker images for every robot's rig.
//!
//! For each robot 1..N and each face of the rig (the reference rig's faces 1..5, or those of
//! `--rig FILE`) writes `robotR-faceF.png` (exact raster, for tests and screens) and
//! `robotR-faceF.svg` (vector, sized in millimetres for printing at the rig's cell size),
//! plus `markers.json` listing every marker with its code and the exact pixel corners of its
//! black border in the PNG. A `(robot, face)` to which the rig's marker table gives no marker
//! is skipped.
//!
//! With `--dictionary NAME --ids LIST [--size-mm N]` it prints standard (OpenCV/AprilTag)
//! markers instead: `NAME-ID.png` and `.svg` (black border `N` mm wide, one white cell of
//! margin) and a `markers.json` of `dictionary`, `id`, files, PNG corners and size.

use std::path::{Path, PathBuf};

use clap::Args as ClapArgs;
use fiducial::{Dictionary, RenderOptions, render_marker, render_svg};
use formation_tracker::rig::RigError;
use serde::Serialize;

use super::CliError;
use super::output::Staged;

/// Arguments of `formation-tracker markers`.
#[derive(Debug, ClapArgs)]
pub struct Args {
    /// Directory to write into (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Number of robots (each gets every face of the rig).
    #[arg(long, default_value_t = 4)]
    pub robots: u32,
    /// A rig file (YAML/JSON: faces, geometry, the marker of each robot and face); default:
    /// the reference rig of spec 3.3.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// Pixels per marker cell in the PNGs.
    #[arg(long = "px-per-cell", default_value_t = 20,
          value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub px_per_cell: u32,
    /// Print standard markers instead of the rig's: a dictionary by name (case-insensitive,
    /// e.g. `DICT_4X4_50`, `DICT_APRILTAG_36h11`, `tag36h11`), with `--ids`.
    #[arg(long, value_name = "NAME", requires = "ids", conflicts_with_all = ["rig", "robots"])]
    pub dictionary: Option<String>,
    /// Ids to print with `--dictionary`: `0-9`, `5`, or a list such as `0-3,7,12`.
    #[arg(long, value_name = "LIST", requires = "dictionary")]
    pub ids: Option<String>,
    /// With `--dictionary`: side of the black border, millimetres (default 100).
    #[arg(long = "size-mm", value_name = "MM", requires = "dictionary",
          value_parser = super::numbers::positive, allow_hyphen_values = true)]
    pub size_mm: Option<f64>,
}

/// One line of `markers.json` with `--dictionary`.
#[derive(Debug, Serialize)]
struct StandardEntry {
    /// The dictionary's canonical name.
    dictionary: &'static str,
    /// The marker's id in it.
    id: usize,
    png: String,
    svg: String,
    /// Outer corners of the black border in the PNG (pixel centres at integers), from the
    /// marker's top-left as printed, clockwise.
    corners_px: [[f64; 2]; 4],
    /// Width and height of the black border, metres.
    size_m: [f64; 2],
}

/// Parses `--ids`: comma-separated ids and inclusive ranges `a-b`.
fn parse_ids(text: &str, len: usize) -> Result<Vec<usize>, CliError> {
    let mut out = Vec::new();
    for part in text.split(',').map(str::trim) {
        let bad = || {
            super::Usage(format!(
                "--ids {text}: `{part}` is not an id or a range like 0-9 (from low to high)"
            ))
        };
        let (a, b) = match part.split_once('-') {
            Some((a, b)) => (a.trim(), b.trim()),
            None => (part, part),
        };
        let a: usize = a.parse().map_err(|_| bad())?;
        let b: usize = b.parse().map_err(|_| bad())?;
        if a > b {
            return Err(bad().into());
        }
        if b >= len {
            return Err(super::Usage(format!(
                "--ids {text}: id {b} is beyond the dictionary's {len} ids (0-{})",
                len - 1
            ))
            .into());
        }
        out.extend(a..=b);
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

/// `markers --dictionary NAME --ids LIST [--size-mm N]`.
fn run_standard(args: &Args, name: &str, ids: &str) -> Result<(), CliError> {
    let dict = fiducial::dictionary_by_name(name)
        .map_err(|e| super::Usage(format!("--dictionary {name}: {e}")))?;
    let canonical = dict.name().unwrap_or(fiducial::PAPER_NAME);
    let ids = parse_ids(ids, dict.len())?;
    let size_mm = args.size_mm.unwrap_or(100.0);
    if size_mm.is_nan() || size_mm <= 0.0 {
        return Err(super::Usage(format!("--size-mm {size_mm}: must be positive")).into());
    }
    let family = dict.family();
    let cell_mm = size_mm / f64::from(family.width_cells());
    let options = RenderOptions {
        px_per_cell: args.px_per_cell,
        quiet_cells: 1,
    };
    super::prepare_out_dir(&args.out)?;
    let mut staged = Staged::new();
    let size_m = [
        size_mm / 1000.0,
        cell_mm * f64::from(family.height_cells()) / 1000.0,
    ];
    let mut entries = Vec::new();
    for id in ids {
        let code = dict.codes()[id];
        let stem = format!("{canonical}-{id}");
        let marker = render_marker(family, code, &options)?;
        let corners_px = marker.corners().map(|p| [p.x, p.y]);
        let png = format!("{stem}.png");
        let path = args.out.join(&png);
        let px_per_m = f64::from(args.px_per_cell) / (cell_mm / 1000.0);
        write_png_at_scale(&staged.path(&path), &marker.into_gray_image(), px_per_m)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        let svg = format!("{stem}.svg");
        staged.write(&args.out.join(&svg), render_svg(family, code, cell_mm, 1)?)?;
        entries.push(StandardEntry {
            dictionary: canonical,
            id,
            png,
            svg,
            corners_px,
            size_m,
        });
    }
    write_index(staged, &args.out, &entries)?;
    super::progress::errln!(
        "markers: wrote {} {canonical} markers ({size_mm} mm) to {}",
        entries.len(),
        args.out.display()
    );
    Ok(())
}

/// One line of `markers.json`.
#[derive(Debug, Serialize)]
struct Entry {
    robot: u32,
    face: u8,
    /// Dictionary index (the reference rig: `(robot - 1) * 5 + (face - 1)`).
    index: usize,
    code: u64,
    png: String,
    svg: String,
    /// Outer corners of the black border in the PNG (pixel centres at integers), NW, NE,
    /// SE, SW.
    corners_px: [[f64; 2]; 4],
    /// Width and height of the black border, metres.
    size_m: [f64; 2],
}

/// Writes the markers and `markers.json`.
pub fn run(args: &Args) -> Result<(), CliError> {
    if let Some(rig) = &args.rig {
        // markers.json (and the images) go into --out: never onto the rig file read.
        let index = args.out.join("markers.json");
        super::output::refuse_inputs_as_outputs(&[("--out", &index)], &[("--rig", rig)])?;
    }
    if let (Some(name), Some(ids)) = (&args.dictionary, &args.ids) {
        return run_standard(args, name, ids);
    }
    let rig = super::load_rig(args.rig.as_deref(), Dictionary::paper())?;
    let dict = rig.marker_dictionary()?;
    if args.robots == 0 {
        return Err(super::Usage("--robots must be at least 1".into()).into());
    }
    let max = rig.max_robots(dict);
    if rig.markers.is_none() && args.robots > max {
        return Err(super::Usage(format!(
            "--robots {} is more than the {max} robots the dictionary supports ({} codes, {} \
             faces each)",
            args.robots,
            dict.len(),
            rig.faces.len()
        ))
        .into());
    }
    let options = RenderOptions {
        px_per_cell: args.px_per_cell,
        quiet_cells: 1,
    };
    super::prepare_out_dir(&args.out)?;
    let mut staged = Staged::new();
    let family = rig.geometry.family()?;
    let size_m = rig.geometry.marker_size_m()?;
    let mut entries = Vec::new();
    for robot in 1..=args.robots {
        for face in rig.faces.iter().map(|f| f.face) {
            let code = match rig.code(dict, robot, face) {
                Ok(code) => code,
                Err(RigError::NoMarker { .. }) => continue,
                Err(e) => return Err(e.into()),
            };
            let index = rig
                .index_of(robot, face)
                .ok_or(RigError::NoMarker { robot, face })?;
            let stem = format!("robot{robot}-face{face}");
            let marker = render_marker(family, code, &options)?;
            let corners_px = marker.corners().map(|p| [p.x, p.y]);
            let png = format!("{stem}.png");
            let path = args.out.join(&png);
            let px_per_m = f64::from(args.px_per_cell) / rig.geometry.cell_size_m;
            write_png_at_scale(&staged.path(&path), &marker.into_gray_image(), px_per_m)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            let svg = format!("{stem}.svg");
            staged.write(
                &args.out.join(&svg),
                render_svg(family, code, rig.geometry.cell_size_m * 1000.0, 1)?,
            )?;
            entries.push(Entry {
                robot,
                face,
                index,
                code,
                png,
                svg,
                corners_px,
                size_m,
            });
        }
    }
    write_index(staged, &args.out, &entries)?;
    super::progress::errln!(
        "markers: wrote {} markers ({} robots x {} faces) to {}",
        entries.len(),
        args.robots,
        rig.faces.len(),
        args.out.display()
    );
    Ok(())
}

/// Writes `markers.json` (the index of the markers staged) and renames every file into place.
fn write_index(
    mut staged: Staged,
    out: &Path,
    entries: &[impl serde::Serialize],
) -> Result<(), CliError> {
    staged.write(
        &out.join("markers.json"),
        serde_json::to_string_pretty(entries)? + "\n",
    )?;
    staged.commit()
}

/// Writes a grey PNG whose `pHYs` chunk says `px_per_m` pixels per metre, so that printing
/// it at its stored resolution gives the marker its size in `markers.json`.
fn write_png_at_scale(
    path: &Path,
    image: &image::GrayImage,
    px_per_m: f64,
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut encoder = png::Encoder::new(file, image.width(), image.height());
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let ppu = px_per_m.round() as u32;
    encoder.set_pixel_dims(Some(png::PixelDimensions {
        xppu: ppu,
        yppu: ppu,
        unit: png::Unit::Meter,
    }));
    let mut writer = encoder.write_header()?;
    writer.write_image_data(image.as_raw())?;
    writer.finish()?;
    Ok(())
}
