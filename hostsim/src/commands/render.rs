//! The `render` command: every view of a scene rendered on the machine that its flags and
//! the scene describe, every view checked before the first image is written, then each
//! view's images, the report and the summary. [`run`] is the whole command, for the command
//! line and for tests alike.

use crate::input::scene::{Scene, ViewJob};
use crate::memory::budget::Profile;
use crate::memory::storage::SkipMode;
use crate::output::files::{check_writable, stdout, write_atomic, write_png};
use crate::output::report::{summary, BalanceReport, FailedView, LostPixels, Report, ViewReport};
use crate::run::render::{preflight, render_cut, Fabric, Machine};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::cell::Cell;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use voxcube_kernel::node::worker::Generation;
use voxcube_kernel::trace::view::{Accuracy, View};

/// The `render` command's flags.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {
    /// Scene file (TOML). Omit for the built-in default scene.
    pub scene: Option<PathBuf>,
    /// Folder for the images, `<dataset>-<view>.png`.
    #[arg(short, long, default_value = "out")]
    pub out: PathBuf,
    /// Also write the per-view report as JSON here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
    /// Nodes (a power of two), overriding every view's `nodes`.
    #[arg(long)]
    pub nodes: Option<u32>,
    /// Clusters (a power of two, at most the nodes), overriding every view's `clusters`.
    #[arg(long)]
    pub clusters: Option<u32>,
    /// What carries the work: direct (one node, in process), sim (the deterministic
    /// simulator), threads (a thread per node, for wall-clock speed) or mpi (ranks under
    /// mpirun, in a build with the `mpi` feature). Default: direct on one node, sim on
    /// more.
    #[arg(long, value_enum)]
    pub fabric: Option<FabricArg>,
    /// Scheduler seed of the sim fabric: the same seed gives the same run.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Who generates primary rays: every worker for its slab (the paper's choice), or ring
    /// position 0 for its whole cluster.
    #[arg(long, value_enum, default_value_t = GenerationArg::Distributed)]
    pub generation: GenerationArg,
    /// Receive-buffer bytes per node (sim): sets `i_max`; too small for any ray to start
    /// is refused, naming the smallest that works.
    #[arg(long)]
    pub buffer: Option<usize>,
    /// The machine profile whose node memory every node must fit.
    #[arg(long, value_enum, default_value_t = ProfileArg::Ncube2)]
    pub machine: ProfileArg,
    /// OS threads of the threads fabric (0: one per core, the measured best here).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Do not skip empty space (a debug option: it changes no pixel, only the time).
    #[arg(long)]
    pub no_skip: bool,
    /// Skip empty space one block per jump, not leaping over every empty block around
    /// (a debug option: it changes no pixel, only the time).
    #[arg(long)]
    pub no_leap: bool,
    /// Skip no single empty cell inside a block that is not empty (a debug option: it
    /// changes no pixel, only the time).
    #[arg(long)]
    pub no_cells: bool,
    /// Leap over empty cells no further than one block's cell mask shows (scanning or
    /// jumping inside it), not by the distances between the cells that may show (a debug
    /// option: it changes no pixel, only the time).
    #[arg(long)]
    pub no_cell_leaps: bool,
    /// Set up every primary ray on every node that walks its pixel, not passing over the
    /// pixels of a row a node certainly does not start or that certainly miss (a debug
    /// option: it changes no pixel, only the time).
    #[arg(long)]
    pub no_row_leaps: bool,
    /// Leap through the empty cells before a primary ray's first cell that may show,
    /// not passing over them at once by its pixel's depth bound (a debug option: it
    /// changes no pixel, only the time).
    #[arg(long)]
    pub no_depths: bool,
    /// Compute the fast tier's node lanes on the fly where shading reads them, holding no
    /// node field (a debug option: it changes no pixel, only the time and the memory).
    #[arg(long)]
    pub no_node_field: bool,
    /// Build each view's cell masks from the nodes, holding no cells' value ranges built
    /// once per volume (a debug option: it changes no pixel, only the time and the memory).
    #[arg(long)]
    pub no_cell_ranges: bool,
    /// Inject a fault: node NODE stops answering after STEPS of its polls (on threads, of
    /// those that did something; with `:exit`, on MPI, its rank's process exits instead: a
    /// crash). The host declares it lost and the surviving clusters re-trace its cluster's
    /// unfinished rows: the same image, the loss named in a warning and the report. Given
    /// twice, the second node (of another cluster) stops after STEPS of its polls in that
    /// re-trace.
    #[arg(long, value_name = "NODE@STEPS[:exit]", value_parser = parse_stop)]
    pub stop_node: Vec<(u16, u64, bool)>,
    /// Seconds the threads and MPI hosts wait without hearing from a node before they
    /// declare it lost (the simulator declares a stopped node lost once nothing else can
    /// happen).
    #[arg(long, value_name = "SECONDS", default_value_t = 2.0, value_parser = parse_seconds)]
    pub lost_after: f64,
    /// The accuracy tier of every view, overriding each view's `accuracy`: exact (the
    /// reference image) or fast (the approximations production ray casters make, each
    /// named in the report).
    #[arg(long, value_parser = accuracy_names())]
    pub accuracy: Option<Accuracy>,
    /// Write the simulator's timeline of the run in virtual time on the --machine profile
    /// (each node's compute, send, receive, test and idle spans) as Chrome trace-event
    /// JSON, which Perfetto and chrome://tracing open. Needs --fabric sim; with several
    /// views, `FILE` gets each view's name before its extension.
    #[arg(long, value_name = "FILE.json")]
    pub trace: Option<PathBuf>,
    /// Render every view as an orbit of N frames turning once around the volume (about
    /// the up axis through the target, at one scale): the frames as
    /// `<dataset>-<view>-000.png` … and an animated `<dataset>-<view>.gif`.
    #[arg(long, value_name = "N")]
    pub orbit: Option<u32>,
    /// Balance every view's slabs first, as the paper does: one cluster traces a probe
    /// of about 32x32 primary rays, timed by the --machine profile, and the slab sizes
    /// follow the workers' times. The nodes start on uniform slabs and shift planes to
    /// their neighbours by message, on every fabric. Also a view's `balance = true`.
    /// Changes no pixel.
    #[arg(long)]
    pub balance: bool,
}

/// `--fabric` values.
/// `--fabric` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FabricArg {
    /// One node, in process.
    Direct,
    /// The deterministic simulator.
    Sim,
    /// OS threads (one per core), for wall-clock speed.
    Threads,
    /// MPI: run under `mpirun -np <nodes + 1>` (built with the `mpi` feature).
    #[cfg(feature = "mpi")]
    Mpi,
}

/// `--machine` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ProfileArg {
    /// The paper's nCUBE 2: 4 MiB per node.
    Ncube2,
    /// A modern cluster node: 1 GiB per node.
    Modern,
    /// This machine: its physical memory shared evenly among the nodes, which run in this
    /// process (direct, sim, threads); timed as modern. What a workstation gives a volume.
    Host,
}

impl ProfileArg {
    /// The shipped profile whose costs time this one's work.
    fn timing(self) -> &'static str {
        match self {
            ProfileArg::Ncube2 => "ncube2",
            ProfileArg::Modern | ProfileArg::Host => "modern",
        }
    }

    /// The memory of each node of `machine` on this profile.
    fn profile(self, machine: &Machine) -> Result<Profile, String> {
        match self {
            ProfileArg::Ncube2 => Ok(Profile::ncube2()),
            ProfileArg::Modern => Profile::builtin("modern")
                .ok_or_else(|| "the shipped modern profile is missing".to_string()),
            // An MPI rank may run on another machine, whose memory this one cannot know, and
            // every rank must budget alike.
            ProfileArg::Host if machine.fabric == Fabric::Mpi => Err(concat!(
                "--machine host shares this machine's memory among nodes that run in this ",
                "process (direct, sim, threads); MPI ranks are cluster nodes: give --machine ",
                "modern or ncube2"
            )
            .to_string()),
            ProfileArg::Host => Profile::host(machine.nodes).ok_or_else(|| {
                concat!(
                    "--machine host: this system does not say how much memory it has (no ",
                    "MemTotal in /proc/meminfo); give --machine modern or ncube2"
                )
                .to_string()
            }),
        }
    }
}

/// `--accuracy` values: the kernel's tiers by their names, listed in `--help`.
fn accuracy_names() -> impl clap::builder::TypedValueParser<Value = Accuracy> {
    use clap::builder::TypedValueParser;
    let names = Accuracy::ALL.map(Accuracy::name);
    // Only the listed names get through the parser, each a tier's own.
    clap::builder::PossibleValuesParser::new(names)
        .map(|name: String| Accuracy::from_name(&name).unwrap_or_default())
}

/// `--generation` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GenerationArg {
    /// Each worker generates the primary rays that start in its slab.
    Distributed,
    /// Ring position 0 generates all and sends them.
    Centralized,
}

/// The machine for one view: the scene's nodes and clusters unless overridden.
#[allow(clippy::too_many_arguments, reason = "one call site: the render flags")]
fn machine(
    view: &ViewJob,
    nodes: Option<u32>,
    clusters: Option<u32>,
    fabric: Option<FabricArg>,
    seed: u64,
    generation: GenerationArg,
    buffer: Option<usize>,
) -> Result<Machine, String> {
    let n = nodes.unwrap_or(view.nodes);
    let m = clusters.unwrap_or(if nodes.is_some() { 1 } else { view.clusters });
    if !n.is_power_of_two() || n > 1024 {
        return Err(format!(
            "--nodes {n}: a hypercube has a power of two of nodes, 1 to 1024"
        ));
    }
    if !m.is_power_of_two() || m > n {
        return Err(format!(
            "--clusters {m}: a power of two, at most the {n} nodes"
        ));
    }
    let fabric = match fabric {
        Some(FabricArg::Direct) => Fabric::Direct,
        Some(FabricArg::Sim) => Fabric::Sim,
        Some(FabricArg::Threads) => Fabric::Threads,
        #[cfg(feature = "mpi")]
        Some(FabricArg::Mpi) => Fabric::Mpi,
        None if n == 1 => Fabric::Direct,
        None => Fabric::Sim,
    };
    let generation = match generation {
        GenerationArg::Distributed => Generation::Distributed,
        GenerationArg::Centralized => Generation::Centralized,
    };
    Ok(Machine {
        generation,
        buffer_bytes: buffer,
        ..Machine::new(fabric, n, m, seed)
    })
}

/// A positive, finite number of seconds.
fn parse_seconds(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 && s <= 86_400.0 => Ok(s),
        _ => Err(format!(
            "`{text}`: expected seconds, more than 0 and at most a day"
        )),
    }
}

/// `NODE@STEPS[:exit]` of `--stop-node`: the node, its steps, and whether it crashes.
fn parse_stop(text: &str) -> Result<(u16, u64, bool), String> {
    let (text, crash) = match text.strip_suffix(":exit") {
        Some(stop) => (stop, true),
        None => (text, false),
    };
    let (node, steps) = text
        .split_once('@')
        .ok_or_else(|| format!("`{text}`: expected NODE@STEPS[:exit], e.g. 3@200"))?;
    let node = node
        .trim()
        .parse()
        .map_err(|_| format!("`{node}`: a node id, 0 to 65534"))?;
    let steps = steps
        .trim()
        .parse()
        .map_err(|_| format!("`{steps}`: a number of polls"))?;
    Ok((node, steps, crash))
}

/// Render every view of the scene `args` names (the built-in default scene if none).
pub fn run(args: RenderArgs) -> Result<(), Box<dyn std::error::Error>> {
    let RenderArgs {
        scene,
        out,
        report,
        quiet,
        nodes,
        clusters,
        fabric,
        seed,
        generation,
        buffer,
        machine: profile,
        threads,
        no_skip,
        no_leap,
        no_cells,
        no_cell_leaps,
        no_row_leaps,
        no_depths,
        no_node_field,
        no_cell_ranges,
        stop_node,
        lost_after,
        accuracy,
        orbit,
        trace,
        balance,
    } = args;
    let (scene, name) = match &scene {
        Some(path) => (Scene::from_file(path)?, path.display().to_string()),
        None => (
            Scene::default_scene()?,
            "<built-in default scene>".to_string(),
        ),
    };
    let scene = match accuracy {
        Some(tier) => scene.with_accuracy(tier),
        None => scene,
    };
    // A dataset whose grid the scene gives is checked against the machine before a sample
    // is generated or read: a volume no machine here holds is refused at once, not after
    // minutes of loading, or never for want of memory.
    scene.check_before_loading(orbit, |dataset, volume, views| {
        for v in views {
            let mut m = machine(v, nodes, clusters, fabric, seed, generation, buffer)
                .map_err(|e| format!("{dataset}/{}: {e}", v.name))?;
            m.profile = profile
                .profile(&m)
                .map_err(|e| format!("{dataset}/{}: {e}", v.name))?;
            preflight(volume, &v.view, &m).map_err(|e| format!("{dataset}/{}: {e}", v.name))?;
        }
        Ok::<(), Box<dyn std::error::Error>>(())
    })?;
    // MPI first where the views render on it: a node's rank loads only the planes its slab
    // stores, where it can, and must know which node it runs.
    #[cfg(feature = "mpi")]
    let mpi_universe = match fabric {
        Some(FabricArg::Mpi) => Some(mpi_init()?),
        _ => None,
    };
    #[cfg(feature = "mpi")]
    let mpi_world = mpi_universe.as_ref().map(|u| u.world());
    #[cfg(feature = "mpi")]
    let window = mpi_world.as_ref().map(|world| {
        use mpi::topology::Communicator;
        let node = u16::try_from(world.rank() - 1).ok();
        move |grid: &voxcube_kernel::volume::grid::Grid, views: &[ViewJob]| {
            rank_window(node, grid, views, (nodes, clusters, balance))
        }
    });
    #[cfg(feature = "mpi")]
    let window = window
        .as_ref()
        .map(|w| w as crate::input::scene::Window<'_>);
    #[cfg(not(feature = "mpi"))]
    let window = None;
    // Everything is loaded and checked before the first image is written.
    let jobs = scene.load_windowed(orbit, window)?;
    let mut plan = Vec::new();
    for job in &jobs {
        for v in &job.views {
            let mut m = machine(v, nodes, clusters, fabric, seed, generation, buffer)
                .map_err(|e| format!("{}/{}: {e}", job.name, v.name))?;
            m.threads = threads;
            m.skipping = SkipMode {
                skip: !no_skip,
                leap: !no_leap,
                cells: !no_cells,
                cell_leaps: !no_cell_leaps,
                rows: !no_row_leaps,
                depths: !no_depths,
                nodes: !no_node_field,
                ranges: !no_cell_ranges,
            };
            m.profile = profile
                .profile(&m)
                .map_err(|e| format!("{}/{}: {e}", job.name, v.name))?;
            m.lost_after = Duration::from_secs_f64(lost_after);
            for (i, &(node, steps, crash)) in stop_node.iter().enumerate() {
                let name = m.fabric.name();
                if m.fabric == Fabric::Direct {
                    return Err(format!("{}/{}: --stop-node injects a fault into a machine of nodes (sim, threads, mpi); this view renders on {name}", job.name, v.name).into());
                }
                if u32::from(node) >= m.nodes {
                    return Err(format!(
                        "{}/{}: --stop-node {node}: the machine has nodes 0 to {}",
                        job.name,
                        v.name,
                        m.nodes - 1
                    )
                    .into());
                }
                let cluster = |n: u16| u32::from(n) / m.cluster_size().max(1);
                match (i, m.stop) {
                    (0, _) => {
                        m.stop = Some((node, steps));
                        m.crash = crash;
                    }
                    (1, Some((first, _))) if crash => {
                        return Err(format!("--stop-node {node}@{steps}:exit: `:exit` is for the first fault only (node {first})").into());
                    }
                    (1, Some((first, _))) if cluster(first) == cluster(node) => {
                        return Err(format!("{}/{}: --stop-node {node}: a second fault stops a node in the re-trace of node {first}'s cluster, so it must be in another cluster (clusters of {})", job.name, v.name, m.cluster_size()).into());
                    }
                    (1, _) => m.retrace_stop = Some((node, steps)),
                    _ => {
                        return Err("--stop-node: at most twice (a node in the frame, then one in its re-trace)".into());
                    }
                }
            }
            if trace.is_some() {
                if m.fabric != Fabric::Sim {
                    return Err(format!(
                        "{}/{}: --trace records the simulator's virtual time: add --fabric sim (this view runs on {})",
                        job.name, v.name, m.fabric.name()
                    )
                    .into());
                }
                m.timeline = Some(profile.timing());
            }
            // Configuration errors up front: nothing renders if any view cannot.
            preflight(&job.volume, &v.view, &m)
                .map_err(|e| format!("{}/{}: {e}", job.name, v.name))?;
            plan.push((job, v, m));
        }
    }
    // Every output is checked before the first view renders: a bad path fails now, not
    // after minutes of work.
    if out.exists() && !out.is_dir() {
        return Err(format!(
            "{}: -o names a file; expected a folder for the images",
            out.display()
        )
        .into());
    }
    std::fs::create_dir_all(&out)
        .map_err(|e| format!("{}: cannot create folder: {e}", out.display()))?;
    for (job, v, _) in &plan {
        check_writable(&out.join(format!("{}-{}.png", job.name, v.name)))?;
    }
    if let Some(path) = &report {
        check_writable(path)?;
    }
    let single = plan.len() == 1;
    let trace_path = |dataset: &str, view: &str| -> Option<PathBuf> {
        let path = trace.as_ref()?;
        if single {
            return Some(path.clone());
        }
        let stem = path.file_stem().unwrap_or_default().to_string_lossy();
        let ext = path
            .extension()
            .map_or(String::new(), |e| format!(".{}", e.to_string_lossy()));
        Some(path.with_file_name(format!("{stem}-{dataset}-{view}{ext}")))
    };
    for (job, v, _) in &plan {
        if let Some(path) = trace_path(&job.name, &v.name) {
            check_writable(&path)?;
        }
    }
    for (job, v, _) in &plan {
        if let Some(o) = v.orbit.as_ref().filter(|o| o.frame == 0) {
            check_writable(&out.join(format!("{}-{}.gif", job.name, o.view)))?;
        }
    }
    // The universe finalises MPI when dropped, at the end of this command on every rank.
    #[cfg(feature = "mpi")]
    if let Some(world) = &mpi_world {
        mpi_check(world, &plan)?;
    }
    #[cfg(feature = "mpi")]
    if let Some(world) = &mpi_world {
        use mpi::topology::Communicator;
        if world.rank() != 0 {
            // A node rank: serve every view's node, write nothing.
            for (job, v, machine) in &plan {
                let balanced = (balance || v.balance) && machine.cluster_size() > 1;
                if let Err(e) = mpi_serve(world, &job.volume, &v.view, machine, balanced) {
                    eprintln!(
                        "voxcube: error: rank {}: {}/{}: {e}",
                        world.rank(),
                        job.name,
                        v.name
                    );
                    world.abort(0);
                }
            }
            crate::fabric::mpi::await_end(world);
            return Ok(());
        }
    }
    let mut views = Vec::new();
    let mut animation: Vec<image::RgbaImage> = Vec::new();
    for (job, v, machine) in plan {
        // Written before each view: a process ended during it (a rank's death ends an
        // MPI job at once) leaves a report of the views finished and the one cut short.
        // A FIFO or device gets the final report only.
        if let Some(path) = report
            .as_ref()
            .filter(|p| crate::output::files::rewritable(p))
        {
            Report {
                scene: &name,
                views: &views,
                failed: Some(FailedView {
                    dataset: job.name.clone(),
                    view: v.name.clone(),
                    error: "the run ended before this view was finished".into(),
                    lost: None,
                }),
            }
            .write(path)?;
        }
        let bar =
            ProgressBar::with_draw_target(Some(v.view.pixel_count()), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{prefix} [{bar:40}] {pos}/{len} pixels, {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_prefix(format!("{}/{}", job.name, v.name));
        let started = Instant::now();
        let shown = Cell::new(false);
        // Shown only on a terminal, only without --quiet, and only past a second.
        let progress = |done: u64| {
            if !quiet && !shown.get() && started.elapsed() > Duration::from_secs(1) {
                bar.set_draw_target(ProgressDrawTarget::stderr());
                shown.set(true);
            }
            bar.set_position(done);
        };
        let balanced = if (balance || v.balance) && machine.cluster_size() > 1 {
            match balance_view(&job.volume, &v.view, &machine, profile) {
                Ok(b) => Some(b),
                Err(e) => {
                    let e = format!("{}/{}: {e}", job.name, v.name);
                    // The node ranks wait for the cuts: stop them all, never a hang.
                    #[cfg(feature = "mpi")]
                    if let Some(world) = &mpi_world {
                        eprintln!("voxcube: error: {e}");
                        mpi::topology::Communicator::abort(world, 1);
                    }
                    return Err(e.into());
                }
            }
        } else {
            None
        };
        let cuts = balanced.as_ref().map(|b| b.cuts_used.as_slice());
        let rendered = match machine.fabric {
            #[cfg(feature = "mpi")]
            Fabric::Mpi => {
                let world = mpi_world.as_ref().ok_or("MPI is not initialised")?;
                mpi_host(world, &job.volume, &v.view, &machine, cuts).map_err(|e| {
                    let lost = e
                        .downcast_ref::<crate::fabric::RunError>()
                        .and_then(LostPixels::of);
                    (e.to_string(), lost)
                })
            }
            _ => render_cut(&job.volume, &v.view, &machine, cuts, &progress).map_err(|e| {
                let lost = match &e {
                    crate::run::render::RenderError::Run { source, .. } => LostPixels::of(source),
                    _ => None,
                };
                (e.to_string(), lost)
            }),
        };
        let rendered = match rendered {
            Ok(rendered) => rendered,
            Err((error, lost)) => {
                let error = format!("{}/{}: {error}", job.name, v.name);
                // The views before this one stand: the report says what was written
                // and what this view lost.
                if let Some(path) = &report {
                    let failed = FailedView {
                        dataset: job.name.clone(),
                        view: v.name.clone(),
                        error: error.clone(),
                        lost,
                    };
                    Report {
                        scene: &name,
                        views: &views,
                        failed: Some(failed),
                    }
                    .write(path)?;
                }
                // Stop every rank: nothing may hang on a lost node.
                #[cfg(feature = "mpi")]
                if let Some(world) = &mpi_world {
                    eprintln!("voxcube: error: {error}");
                    mpi::topology::Communicator::abort(world, 1);
                }
                return Err(error.into());
            }
        };
        bar.finish_and_clear();
        let image = out.join(format!("{}-{}.png", job.name, v.name));
        let pixels = rendered.bytes();
        // A host that holds no samples (MPI ranks each hold their own) takes the range of
        // values its nodes reported.
        let reported = rendered.distributed.as_ref().and_then(|d| d.data_range);
        let range = match job.volume.is_whole() {
            true => job.volume.held_range(),
            false => reported,
        };
        let mut warnings = crate::input::framing::blank_reasons(range, &job.volume.grid, &v.view);
        if warnings.is_empty() && pixels.chunks_exact(4).all(|p| p == &pixels[..4]) {
            warnings.push("the view drew nothing: every pixel is the background".into());
        }
        if let Some(r) = rendered
            .distributed
            .as_ref()
            .and_then(|d| d.recovery.as_ref())
        {
            warnings.push(r.to_string());
        }
        if !quiet {
            for w in &warnings {
                eprintln!("voxcube: warning: {}/{}: {w}", job.name, v.name);
            }
        }
        write_png(&image, rendered.width, rendered.height, &pixels)?;
        if let Some(o) = &v.orbit {
            animation.push(
                image::RgbaImage::from_raw(rendered.width, rendered.height, pixels.clone())
                    .ok_or("an orbit frame's pixels do not fill its image")?,
            );
            if o.frame + 1 == o.frames {
                let gif = out.join(format!("{}-{}.gif", job.name, o.view));
                write_gif(&gif, std::mem::take(&mut animation))?;
            }
        }
        let mut report = ViewReport::new(
            &job.name,
            &v.name,
            image.display().to_string(),
            &v.view,
            &machine,
            &rendered,
        );
        if let Some(path) = trace_path(&job.name, &v.name) {
            let time = rendered
                .distributed
                .as_ref()
                .and_then(|d| d.time.as_ref())
                .ok_or("--trace: the simulator returned no timeline")?;
            let json = crate::run::timeline::chrome_trace(time, machine.cluster_size());
            write_atomic(&path, json.to_string().as_bytes())?;
        }
        report.balance = balanced;
        report.warnings = warnings;
        views.push(report);
    }
    if !quiet {
        stdout(&summary(&views))?;
    }
    if let Some(path) = report {
        Report {
            scene: &name,
            views: &views,
            failed: None,
        }
        .write(&path)?;
    }
    // Every rank finalises together; a hung rank never would: with everything written,
    // the job then ends here, successfully (the warnings named what was lost).
    #[cfg(feature = "mpi")]
    if let Some(world) = &mpi_world {
        crate::fabric::mpi::end(world, Duration::from_secs_f64(lost_after));
    }
    Ok(())
}

/// Write `frames` as an animated GIF that loops, a tenth of a second a frame.
fn write_gif(path: &std::path::Path, frames: Vec<image::RgbaImage>) -> Result<(), String> {
    let mut bytes = Vec::new();
    {
        let mut encoder = image::codecs::gif::GifEncoder::new_with_speed(&mut bytes, 10);
        encoder
            .set_repeat(image::codecs::gif::Repeat::Infinite)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let delay = image::Delay::from_numer_denom_ms(100, 1);
        encoder
            .encode_frames(
                frames
                    .into_iter()
                    .map(|f| image::Frame::from_parts(f, 0, 0, delay)),
            )
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    write_atomic(path, &bytes).map_err(|e| e.to_string())
}

/// Static load balancing of `view` for `machine`'s clusters, timed by the `profile` chosen
/// with `--machine`, each slab kept within the node memory of `machine`'s profile.
fn balance_view(
    volume: &crate::input::dataset::Volume,
    view: &View,
    machine: &Machine,
    profile: ProfileArg,
) -> Result<BalanceReport, String> {
    let name = profile.timing();
    let timing = crate::profile::MachineProfile::load(name).map_err(|e| e.to_string())?;
    let size = machine.cluster_size();
    let buffer = machine.sim_config().map_err(|e| e.to_string())?.buffer();
    let cap = crate::memory::budget::max_owned_planes(
        machine.profile,
        &volume.grid,
        volume.data.kind().bytes(),
        crate::memory::budget::ViewNeeds::of(view),
        buffer,
    );
    let b = crate::run::balance::balance(volume, view, &timing, size, machine.skipping, cap)
        .map_err(|e| e.to_string())?;
    let probe = crate::run::balance::probe_view(view, volume).map_err(|e| e.to_string())?;
    let rays = [probe.spec().width, probe.spec().height];
    Ok(BalanceReport::new(&b, rays, name))
}

/// The X planes node `node` stores of a dataset on `grid` in any of `views` (on the machine
/// `--nodes`, `--clusters` and each view's own make, slabs uniform): their hull; for the
/// host (`None`), which traces nothing, no plane; `None`, for every plane, where a slab is
/// balanced (a re-trace then loads the host's cuts at once) or the node has no place.
#[cfg(feature = "mpi")]
fn rank_window(
    node: Option<u16>,
    grid: &voxcube_kernel::volume::grid::Grid,
    views: &[ViewJob],
    (nodes, clusters, balance): (Option<u32>, Option<u32>, bool),
) -> Option<std::ops::Range<u32>> {
    use voxcube_kernel::node::partition::Partition;
    use voxcube_kernel::node::topology::Layout;
    let nx = grid.dims()[0];
    // The host holds no plane whatever the views; a node the hull of its slabs'.
    let mut hull: Option<std::ops::Range<u32>> = match node {
        None => Some(0..0),
        Some(_) => None,
    };
    for v in views {
        let n = nodes.unwrap_or(v.nodes);
        let m = clusters.unwrap_or(if nodes.is_some() { 1 } else { v.clusters });
        let placed = node.map_or(0, u32::from) < n;
        if balance || v.balance || !placed || m == 0 || !n.is_multiple_of(m) {
            return None;
        }
        let layout = Layout::new(m, n / m).ok()?;
        let Some(node) = node else {
            continue;
        };
        let planes = Partition::uniform(nx, usize::from(layout.size()))
            .ok()?
            .planes(usize::from(layout.place(node).1));
        let stored =
            voxcube_kernel::volume::slab::stored_planes(grid, planes, v.view.ghost_planes());
        hull = Some(match hull {
            None => stored,
            Some(h) => h.start.min(stored.start)..h.end.max(stored.end),
        });
    }
    hull
}

/// MPI, initialised at the funnelled threading level.
#[cfg(feature = "mpi")]
fn mpi_init() -> Result<mpi::environment::Universe, String> {
    // Funnelled: a node builds its set-up on a thread of its own while its rank's thread,
    // the only one that calls MPI, heartbeats (`crate::fabric::mpi`).
    let (universe, level) = mpi::initialize_with_threading(mpi::Threading::Funneled)
        .ok_or("MPI could not be initialised (is this run under mpirun?)")?;
    if level == mpi::Threading::Single {
        return Err(format!(
            "this MPI library offers the threading level {level:?}; voxcube needs Funneled (a rank's set-up runs on a thread beside the one that calls MPI)"
        ));
    }
    Ok(universe)
}

/// Check that every view of `plan` renders on MPI with as many ranks as its nodes need, and
/// enroll this rank.
#[cfg(feature = "mpi")]
fn mpi_check(
    world: &mpi::topology::SimpleCommunicator,
    plan: &[(&crate::input::scene::DatasetJob, &ViewJob, Machine)],
) -> Result<(), String> {
    use mpi::topology::Communicator;
    if plan.iter().any(|(_, _, m)| m.fabric != Fabric::Mpi) {
        return Err("with --fabric mpi every view renders on MPI".into());
    }
    for (job, v, m) in plan {
        if world.size() as u32 != m.nodes + 1 {
            return Err(format!(
                "{}/{}: {} nodes need {} MPI ranks (the host and one per node): mpirun -np {}; this run has {}",
                job.name,
                v.name,
                m.nodes,
                m.nodes + 1,
                m.nodes + 1,
                world.size()
            ));
        }
    }
    crate::fabric::mpi::enroll(world);
    Ok(())
}

#[cfg(feature = "mpi")]
fn mpi_serve(
    world: &mpi::topology::SimpleCommunicator,
    volume: &crate::input::dataset::Volume,
    view: &View,
    machine: &Machine,
    balanced: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    // Balanced: the node takes the host's cuts and shifts to them.
    let cfg = crate::fabric::RunConfig {
        shift: balanced,
        skipping: crate::run::render::node_skipping(volume, view, machine, balanced),
        ..machine.sim_config()?
    };
    Ok(crate::fabric::mpi::serve(world, volume, view, &cfg)?)
}

#[cfg(feature = "mpi")]
fn mpi_host(
    world: &mpi::topology::SimpleCommunicator,
    volume: &crate::input::dataset::Volume,
    view: &View,
    machine: &Machine,
    cuts: Option<&[u32]>,
) -> Result<crate::run::render::Rendered, Box<dyn std::error::Error>> {
    let cfg = crate::fabric::RunConfig {
        cuts: cuts.map(<[u32]>::to_vec),
        shift: cuts.is_some(),
        skipping: crate::run::render::node_skipping(volume, view, machine, cuts.is_some()),
        ..machine.sim_config()?
    };
    let run = crate::fabric::mpi::host(world, volume, view, &cfg)?;
    Ok(crate::run::render::Rendered::from_run(view, run))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    /// `render`'s flags as the command line would give them, for a call without it.
    #[derive(Parser)]
    struct Flags {
        #[command(flatten)]
        args: RenderArgs,
    }

    fn args(flags: &[&str]) -> RenderArgs {
        Flags::parse_from(std::iter::once("render").chain(flags.iter().copied())).args
    }

    #[test]
    fn the_command_renders_the_default_scene_and_reports_it_without_the_command_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out");
        let report = dir.path().join("report.json");
        let (o, r) = (
            out.to_str().expect("utf-8"),
            report.to_str().expect("utf-8"),
        );
        run(args(&["-o", o, "--report", r, "--quiet"])).expect("the default scene renders");
        assert!(out.join("molecule-paper.png").is_file());
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).expect("the report")).expect("JSON");
        let view = &json["views"][0];
        assert_eq!(view["view"], "paper");
        assert_eq!(view["nan_pixels"], 0);
        assert!(view["operations"]["samples"]
            .as_u64()
            .is_some_and(|n| n > 0));
    }

    #[test]
    fn a_configuration_error_writes_nothing() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("out");
        let o = out.to_str().expect("utf-8");
        // A fault injected into one node in process: there is no machine of nodes to stop.
        let e = run(args(&["-o", o, "--quiet", "--stop-node", "0@5"])).expect_err("refused");
        assert!(e.to_string().contains("--stop-node"), "{e}");
        assert!(
            !out.exists(),
            "nothing is written before every view is checked"
        );
    }
}
