//! The `voxcube` command line: its subcommands and flags, parsed and handed to the modules
//! that do their work (`render` to [`crate::commands::render`], `info` to
//! [`crate::commands::info`], `bench`, `paper`, `accuracy` and `explore` to
//! [`crate::experiments`]; `scene` prints the built-in default scene). Errors go to stderr
//! with a non-zero exit.

use crate::experiments::bench;
use crate::experiments::explore;
use crate::input::scene::DEFAULT_SCENE;
use crate::output::files::{check_writable, stdout, write_atomic};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// The version, and whether this build carries the kernel's test-only faults: a product build
/// says `test faults: none`, which CI checks on the release binary.
const VERSION: &str = if voxcube_kernel::node::worker::TEST_FAULTS {
    concat!(
        env!("CARGO_PKG_VERSION"),
        " (test faults: compiled in, not for use)"
    )
} else {
    concat!(env!("CARGO_PKG_VERSION"), " (test faults: none)")
};

/// voxcube: parallel volume ray tracing after Montani, Perego & Scopigno (1992).
#[derive(Debug, Parser)]
#[command(name = "voxcube", version = VERSION, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
    /// The most samples a volume file's header may declare: checked before anything is
    /// decompressed or kept for them (default 2^32, a 1,625³ volume).
    #[arg(long, global = true, default_value_t = crate::input::formats::DEFAULT_MAX_SAMPLES)]
    pub max_samples: u64,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render every view of every dataset of a scene (the built-in default scene if none).
    Render(crate::commands::render::RenderArgs),
    /// Print the built-in default scene: a complete, commented example of the format.
    Scene,
    /// Describe a volume file, DICOM folder or scene's datasets: grid, type, spacing, values
    /// and their histogram, node memory per cluster size on each machine profile, and
    /// suggested iso values; with --scene, print a ready scene file for the volume instead.
    Info {
        /// A volume file (NIfTI, MetaImage, VTK, NRRD, .den), a DICOM folder, or a scene.
        path: PathBuf,
        /// Print a scene file that renders the volume (a surfaces and a composited view).
        #[arg(long)]
        scene: bool,
    },
    /// Benchmark: the default scene and SOD at 350x250 (dt 1/2) and 1024x768 (dt 1/5), surfaces
    /// and compositing, on the shapes worth comparing here, and VTK in the same run; medians
    /// of several runs, then the speed targets met or not, judged on rounds of VTK and
    /// voxcube back to back.
    Bench {
        /// Runs per configuration (the median is reported), and rounds paired with VTK.
        #[arg(long, default_value_t = 5)]
        runs: usize,
        /// Only the paper's 350x250 at dt 1/2, not also 1024x768 at dt 1/5 (quicker).
        #[arg(long)]
        small: bool,
        /// The SOD volume (left out, with a note, if absent).
        #[arg(long, default_value = "../shared/data/sod-97x97x116.u8.binary")]
        sod: PathBuf,
        /// Instead: how the cost grows with the work, both tiers, on one node and every core:
        /// the molecule resampled to 128³, 256³, 512³ at 350x250 (beside VTK where it is
        /// installed), and 128³ at images up to 2048x1536 (time per evaluated sample and per
        /// pixel); writes scale.txt and scale.svg to --out.
        #[arg(long)]
        scale: bool,
        /// With --scale: the folder for its table and plot.
        #[arg(short, long, default_value = "out/bench")]
        out: PathBuf,
        /// Instead: instructions per frame, per lattice sample and per evaluated sample of each
        /// SOD view at 350x250 on one node, counted by callgrind (needs valgrind): figures that
        /// do not move with the machine's load.
        #[arg(long, conflicts_with = "scale")]
        instructions: bool,
        /// The side that --instructions counts: render this SOD view --frames times and print
        /// its counters.
        #[arg(long, hide = true)]
        count_frame: Option<String>,
        /// With --count-frame: how many frames.
        #[arg(long, hide = true, default_value_t = 1)]
        frames: u32,
    },
    /// The paper's Tables 1-4 in simulated nCUBE 2 time, beside the paper's numbers, with
    /// speedup and efficiency plots and the image.
    Paper {
        /// SOD: the folder holding sod-97x97x116.u8.binary, or that file. A missing SOD is an
        /// error.
        #[arg(long, default_value = "../shared/data")]
        data: PathBuf,
        /// Render the built-in molecule of SOD's size instead of SOD.
        #[arg(long)]
        substitute: bool,
        /// Folder for tables, plots and the image.
        #[arg(short, long, default_value = "out/paper")]
        out: PathBuf,
        /// Machine profile: ncube2, modern, or a profile file.
        #[arg(long, default_value = "ncube2")]
        machine: String,
        /// First fit the profile's two constants (compute `scale`, `message_scale`) on
        /// Table 1 alone, then predict Tables 2-4 with them (about a minute more).
        #[arg(long)]
        fit: bool,
        /// Also write one row's timeline, `NODES/SIZE` (say 128/2: 128 nodes in clusters of
        /// 2), as Chrome trace-event JSON `trace-NODES-SIZE.json` in the output folder.
        #[arg(long, value_name = "NODES/SIZE")]
        trace: Option<String>,
    },
    /// What accuracy costs in time: dt, voxel vs cell model, image size and
    /// the accuracy tiers swept on SOD; wall time, simulated nCUBE 2 time, samples, and error
    /// against a fine exact reference (PSNR, 99th-percentile and max error); a table and a plot.
    Accuracy {
        /// SOD: the folder holding sod-97x97x116.u8.binary, or that file. A missing SOD is an
        /// error.
        #[arg(long, default_value = "../shared/data")]
        data: PathBuf,
        /// Sweep the built-in molecule of SOD's size instead of SOD.
        #[arg(long)]
        substitute: bool,
        /// Folder for the table and the plot.
        #[arg(short, long, default_value = "out/accuracy")]
        out: PathBuf,
        /// Instead: the time-error frontier beside VTK (when peers/setup.sh has installed
        /// it): SOD composited and as a surface at 350x250, VTK and both tiers over a sweep of
        /// dt on every core, each against its own renderer's converged image.
        #[arg(long)]
        frontier: bool,
        /// Timed frames per image of the frontier (the median is reported).
        #[arg(long, default_value_t = 5)]
        runs: usize,
    },
    /// Explore schedules on the simulator: configurations (scenes with shadows and
    /// transparency, cube shapes, buffer sizes) × schedulers × seeds. Prints what was explored,
    /// deadlocks, invariant violations, differing images and the worst buffer use.
    Explore {
        /// Seeds per configuration and scheduler.
        #[arg(long, default_value_t = 4)]
        seeds: u64,
        /// Which configurations: all of them, or only the tight ones (small buffers, shadows).
        #[arg(long, value_enum, default_value_t = ConfigSet::All)]
        configs: ConfigSet,
        /// Ack-counter flow control; `off` is the negative control and should find deadlocks.
        #[arg(long, value_enum, default_value_t = Switch::On)]
        flow_control: Switch,
        /// Receive-buffer bytes per node for every configuration (default: each configuration's own).
        #[arg(long)]
        buffer: Option<usize>,
        /// Instead: walk every schedule of rings of 2 and 3 nodes rendering a handful of rays
        /// (states seen before pruned), and print the distinct states.
        #[arg(long)]
        exhaustive: bool,
        /// Stop a node at a random step of every run (machines of two clusters or more):
        /// every run must end with the fault-free image, the lost cluster's rows re-traced.
        #[arg(long)]
        faults: bool,
    },
}

/// `explore --configs` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ConfigSet {
    /// Every configuration.
    All,
    /// Shadow scenes on rings of 2 or more with small buffers.
    Tight,
}

/// On or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Switch {
    /// On.
    On,
    /// Off.
    Off,
}
/// Where `paper` and `accuracy` take their volume: SOD at `data`, or the substitute.
fn source(data: &std::path::Path, substitute: bool) -> crate::experiments::paper::Source<'_> {
    match substitute {
        true => crate::experiments::paper::Source::Substitute,
        false => crate::experiments::paper::Source::Sod(data),
    }
}

/// Write `text` to `NAME.txt` and `plot` to `NAME.svg` in the folder `out` (made if need be),
/// then print `notes`, `text` and where both went.
fn table_and_plot(
    out: &std::path::Path,
    name: &str,
    (notes, text): (&str, &str),
    plot: impl FnOnce(&std::path::Path) -> Result<(), String>,
) -> Result<(), Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let txt = out.join(format!("{name}.txt"));
    std::fs::write(&txt, text).map_err(|e| format!("{}: {e}", txt.display()))?;
    plot(&out.join(format!("{name}.svg")))?;
    stdout(&format!(
        "{notes}{text}wrote {}/{name}.txt and {name}.svg\n",
        out.display()
    ))?;
    Ok(())
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
    crate::input::formats::set_max_samples(cli.max_samples);
    match cli.command {
        Command::Scene => {
            stdout(DEFAULT_SCENE)?;
            Ok(())
        }
        Command::Info { path, scene } => {
            let volumes = crate::commands::info::volumes(&path)?;
            let text = if scene {
                match &volumes[..] {
                    [(_, volume)] if path.extension().is_none_or(|e| e != "toml") => {
                        crate::commands::info::suggested_scene(&path, volume)?
                    }
                    _ => {
                        return Err(
                            "--scene takes a volume file or DICOM folder, not a scene".into()
                        )
                    }
                }
            } else {
                volumes
                    .iter()
                    .map(|(name, v)| crate::commands::info::describe(name, v))
                    .collect::<Result<Vec<_>, _>>()?
                    .join("\n")
            };
            stdout(&text)?;
            Ok(())
        }
        Command::Paper {
            data,
            substitute,
            out,
            machine,
            trace,
            fit,
        } => {
            let profile = crate::profile::MachineProfile::load(&machine)?;
            let row = trace
                .as_deref()
                .map(|t| {
                    t.split_once('/')
                        .and_then(|(p, s)| Some((p.parse::<u32>().ok()?, s.parse::<u32>().ok()?)))
                        .ok_or_else(|| {
                            format!("--trace {t}: expected NODES/SIZE, for example 128/2")
                        })
                })
                .transpose()?;
            let trace_file = row.map(|(p, s)| out.join(format!("trace-{p}-{s}.json")));
            let mut text = String::new();
            let job = crate::experiments::paper::dataset(source(&data, substitute), &mut text)?;
            if let (Some((p, s)), Some(path)) = (row, &trace_file) {
                std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
                check_writable(path)?;
                let time = crate::experiments::paper::traced(&job, &profile, p, s)?;
                let json = crate::run::timeline::chrome_trace(&time, s);
                write_atomic(path, json.to_string().as_bytes())?;
                text += &format!(
                    "wrote the {p}-node, clusters-of-{s} timeline to {}\n",
                    path.display()
                );
            }
            crate::experiments::paper::run(&job, &profile, &out, &mut text, fit)?;
            stdout(&text)?;
            Ok(())
        }
        Command::Accuracy {
            data,
            substitute,
            out,
            frontier: true,
            runs,
        } => {
            let frontier = crate::experiments::frontier::sweep(source(&data, substitute), runs)?;
            let table = crate::experiments::frontier::table(&frontier);
            table_and_plot(&out, "frontier", ("", &table), |svg| {
                crate::experiments::frontier::plot(svg, &frontier)
            })
        }
        Command::Accuracy {
            data,
            substitute,
            out,
            frontier: false,
            ..
        } => {
            let mut notes = String::new();
            let job = crate::experiments::paper::dataset(source(&data, substitute), &mut notes)?;
            let profile = crate::profile::MachineProfile::ncube2();
            let points = crate::experiments::accuracy::sweep(&job, &profile);
            let table = crate::experiments::accuracy::table(&points);
            table_and_plot(&out, "accuracy", (&notes, &table), |svg| {
                crate::experiments::accuracy::plot(svg, &points)
            })
        }
        Command::Bench {
            count_frame: Some(view),
            frames,
            sod,
            ..
        } => Ok(stdout(&crate::experiments::instructions::count_frames(
            &view, frames, &sod,
        )?)?),
        Command::Bench {
            instructions: true,
            sod,
            ..
        } => {
            let counts = crate::experiments::instructions::run(&sod)?;
            stdout(&crate::experiments::instructions::table(&counts))?;
            Ok(())
        }
        Command::Bench {
            runs,
            scale: true,
            out,
            ..
        } => {
            // Before the sweep's minutes, not after them.
            std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
            let mut notes = String::new();
            let scale = crate::experiments::scale::run(runs, &mut notes)?;
            let table = crate::experiments::scale::table(&scale, runs);
            table_and_plot(&out, "scale", (&notes, &table), |svg| {
                crate::experiments::scale::plot(svg, &scale)
            })
        }
        Command::Bench {
            runs, small, sod, ..
        } => {
            let mut notes = String::new();
            let sizes: &[bench::Size] = if small {
                &[bench::Size::PAPER]
            } else {
                &[bench::Size::PAPER, bench::Size::LARGE]
            };
            let rows = bench::run(runs, sizes, &sod, &mut notes)?;
            // VTK at the large frame too when the bench renders it.
            let large = sizes
                .iter()
                .find(|s| **s == bench::Size::LARGE)
                .map(|s| s.frame());
            let vtk = match crate::experiments::peer::vtk(&sod, runs, large) {
                Ok(t) => t,
                Err(e) => {
                    notes += &format!("VTK peer failed: {e}\n");
                    None
                }
            };
            // Then the targets, each on rounds of VTK and voxcube back to back.
            let paired = match bench::paired(runs, sizes, &sod) {
                Ok(Some(pairs)) => bench::paired_table(&pairs),
                Ok(None) => String::new(),
                Err(e) => format!("paired rounds with VTK failed: {e}\n"),
            };
            stdout(&format!(
                "{notes}{}{}{paired}",
                bench::table(&rows, runs),
                bench::versus_vtk(&rows, vtk)
            ))?;
            Ok(())
        }
        Command::Explore {
            exhaustive: true, ..
        } => {
            let mut text = String::new();
            let mut failed = false;
            for (label, found, reference) in explore::exhaustive_walks()? {
                let same = found.images.len() == 1 && found.images.contains(&reference);
                failed |= found.deadlocks + found.violations > 0 || !same || found.truncated;
                text += &format!(
                    "{label}\n{found}\nthe direct render's image  {}\n\n",
                    if same { "yes" } else { "no" }
                );
            }
            stdout(&text)?;
            if failed {
                return Err("an exhaustive walk found a fault".into());
            }
            Ok(())
        }
        Command::Explore {
            seeds,
            configs,
            flow_control,
            buffer,
            exhaustive: false,
            faults,
        } => {
            let job = explore::scenes()?;
            let mut all = explore::configs(&job);
            if configs == ConfigSet::Tight {
                all.retain(|c| {
                    c.view < 2
                        && c.size >= 2
                        && c.buffer <= voxcube_kernel::node::flow::buffer_bytes(c.size as usize, 8)
                });
            }
            if let Some(bytes) = buffer {
                for c in &mut all {
                    c.buffer = bytes;
                }
            }
            if faults {
                all = explore::recoverable(&all);
            }
            let on = flow_control == Switch::On;
            let found = explore::explore(&job, &all, seeds, &|cfg| {
                cfg.flow_control = on;
                if faults {
                    explore::inject_stop(cfg);
                }
            });
            stdout(&format!(
                "flow control          {}\n{found}",
                if on { "on" } else { "off" }
            ))?;
            if on && found.failures() > 0 {
                return Err(format!(
                    "{} of {} runs failed with flow control on",
                    found.failures(),
                    found.runs
                )
                .into());
            }
            Ok(())
        }
        Command::Render(args) => crate::commands::render::run(args),
    }
}
