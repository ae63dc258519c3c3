//! The `voxcube` command line: `render` a scene (or the built-in default), print the default
//! `scene`. Errors go to stderr with a non-zero exit; nothing is written unless the whole
//! scene loaded and checked.

use crate::output::{write_atomic, write_png};
use crate::render::render;
use crate::report::{summary, Report, ViewReport};
use crate::scene::{Scene, DEFAULT_SCENE};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// voxcube: parallel volume ray tracing after Montani, Perego & Scopigno (1992).
#[derive(Debug, Parser)]
#[command(name = "voxcube", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render every view of every dataset of a scene (the built-in default scene if none).
    Render {
        /// Scene file (TOML). Omit for the built-in default scene.
        scene: Option<PathBuf>,
        /// Folder for the images, `<dataset>-<view>.png`.
        #[arg(short, long, default_value = "out")]
        out: PathBuf,
        /// Also write the per-view report as JSON here.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Print nothing but errors.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Print the built-in default scene: a complete, commented example of the format.
    Scene,
}

/// Run the command line; the process exit code.
pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("voxcube: error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Run a parsed command.
pub fn run(cli: Cli) -> Result<(), Box<dyn std::error::Error>> {
    match cli.command {
        Command::Scene => {
            print!("{DEFAULT_SCENE}");
            Ok(())
        }
        Command::Render {
            scene,
            out,
            report,
            quiet,
        } => {
            let (scene, name) = match &scene {
                Some(path) => (Scene::from_file(path)?, path.display().to_string()),
                None => (
                    Scene::default_scene()?,
                    "<built-in default scene>".to_string(),
                ),
            };
            // Everything is loaded and checked before the first image is written.
            let jobs = scene.load()?;
            std::fs::create_dir_all(&out)
                .map_err(|e| format!("{}: cannot create folder: {e}", out.display()))?;
            let mut views = Vec::new();
            for job in &jobs {
                for v in &job.views {
                    let rendered = render(&job.volume, &v.view)?;
                    let image = out.join(format!("{}-{}.png", job.name, v.name));
                    write_png(&image, rendered.width, rendered.height, &rendered.bytes())?;
                    views.push(ViewReport::new(
                        &job.name,
                        &v.name,
                        image.display().to_string(),
                        &v.view,
                        v.nodes,
                        v.clusters,
                        &rendered,
                    ));
                }
            }
            if !quiet {
                print!("{}", summary(&views));
            }
            if let Some(path) = report {
                let json = serde_json::to_string_pretty(&Report { scene: name, views })?;
                write_atomic(&path, json.as_bytes())?;
            }
            Ok(())
        }
    }
}
