//! `formation-tracker render`: one synthetic frame of a paper scene or a scene file, as PNG,
//! with its ground truth as JSON.

use std::path::PathBuf;
use std::sync::Mutex;

use clap::Args as ClapArgs;
use fiducial::Dictionary;
use formation_sim::paper::paper_scene;
use formation_sim::scene::{SceneSpec, render_scene_with_progress};

use super::CliError;
use super::progress::Progress;

/// Arguments of `formation-tracker render`.
#[derive(Debug, ClapArgs)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["paper_fig", "scene"])))]
pub struct Args {
    /// One of the paper's configurations, Figs. 7 to 11 (spec section 6).
    #[arg(long = "paper-fig", value_name = "N", value_parser = paper_fig)]
    pub paper_fig: Option<u8>,
    /// A scene file (YAML, or JSON when it ends in .json).
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// A rig file (YAML/JSON); default: the reference rig of spec 3.3.
    #[arg(long, value_name = "FILE")]
    pub rig: Option<PathBuf>,
    /// The image to write (PNG).
    #[arg(long, value_name = "IMAGE")]
    pub out: PathBuf,
    /// Where to write the ground truth (JSON).
    #[arg(long, value_name = "JSON")]
    pub truth: Option<PathBuf>,
}

/// A figure of the paper with a scene, 7 to 11.
fn paper_fig(s: &str) -> Result<u8, String> {
    match s.trim().parse::<u8>() {
        Ok(n) if (7..=11).contains(&n) => Ok(n),
        _ => Err(format!(
            "`{s}` is not one of the paper's scene figures, 7 to 11"
        )),
    }
}

/// Renders the scene and writes the image (and the truth).
pub fn run(args: &Args) -> Result<(), CliError> {
    let mut inputs: Vec<(&str, &std::path::Path)> = Vec::new();
    for (name, path) in [("--scene", &args.scene), ("--rig", &args.rig)] {
        if let Some(path) = path {
            inputs.push((name, path));
        }
    }
    super::output::refuse_inputs_as_outputs(&[("--out", &args.out)], &inputs)?;
    if let Some(truth) = &args.truth {
        // The two outputs must differ too: the truth would replace the image.
        inputs.push(("--out", &args.out));
        super::output::refuse_inputs_as_outputs(&[("--truth", truth)], &inputs)?;
    }
    let dict = Dictionary::paper();
    let rig = super::load_rig(args.rig.as_deref(), dict)?;
    let spec = match (&args.paper_fig, &args.scene) {
        (Some(fig), _) => paper_scene(*fig)?,
        (None, Some(path)) => SceneSpec::load(path)?,
        (None, None) => return Err("give --paper-fig N or --scene FILE".into()),
    };
    super::prepare_out_file(&args.out)?;
    if let Some(truth) = &args.truth {
        super::prepare_out_file(truth)?;
    }
    // A large scene takes minutes to trace: progress by rows (a bar on a terminal, status
    // lines in a log, nothing with --quiet).
    let progress = Mutex::new(Progress::new(
        "render",
        "rows",
        Some(spec.camera.height as u64),
    ));
    let rendered = render_scene_with_progress(&spec, &rig, dict, &|done, _| {
        if let Ok(mut p) = progress.lock() {
            p.set(done as u64);
        }
    })?;
    if let Ok(p) = progress.into_inner() {
        p.finish();
    }
    let mut staged = super::output::Staged::new();
    rendered
        .image
        .save_with_format(staged.path(&args.out), image::ImageFormat::Png)
        .map_err(|e| format!("cannot write {}: {e}", args.out.display()))?;
    if let Some(path) = &args.truth {
        staged.write(path, serde_json::to_string_pretty(&rendered.truth)? + "\n")?;
    }
    staged.commit()?;
    let readable: usize = rendered
        .truth
        .robots
        .iter()
        .map(|r| r.faces.iter().filter(|f| f.readable).count())
        .sum();
    super::progress::errln!(
        "render: wrote {} ({} robots, {readable} readable faces)",
        args.out.display(),
        rendered.truth.robots.len()
    );
    Ok(())
}
