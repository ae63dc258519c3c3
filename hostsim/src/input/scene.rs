//! The scene file (the paper's "input file"), TOML: datasets, each with one or more views.
//!
//! Parsing is strict: an unknown key, a wrong type or a value out of range is an error that
//! names the file and the key (`datasets[0].views[1].dt`). Relative dataset paths are resolved
//! against the scene file's folder. A scene is checked whole — every dataset loaded and every
//! view built — before anything is rendered, so a bad scene writes nothing.

use crate::input::builtin;
use crate::input::dataset::Volume;
use crate::input::formats::{self, raw::RawLayout, Endian, FileType, Format, LoadError};
use crate::input::framing::{Frame, Showing};
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use voxcube_kernel::optics::shade::{Light, Shading, MAX_LIGHTS};
use voxcube_kernel::optics::surface::{IsoSurface, MAX_SURFACES};
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::trace::camera::{Camera, Projection};
use voxcube_kernel::trace::view::{Accuracy, Compositing, Mode, View, ViewSpec, DEFAULT_CUTOFF};
use voxcube_kernel::volume::grid::{Grid, Model};
use voxcube_kernel::Vec3;

/// The built-in default scene: the paper's view of the procedural molecule.
pub const DEFAULT_SCENE: &str = include_str!("default_scene.toml");

/// A scene that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The scene file.
        file: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not valid TOML, or a key or type the schema does not have.
    #[error("{file}: {message}")]
    Parse {
        /// The scene file.
        file: String,
        /// The parser's message (line, column, key).
        message: String,
    },
    /// A value out of range or inconsistent with another.
    #[error("{file}: {key}: {message}")]
    Invalid {
        /// The scene file.
        file: String,
        /// Path of the key at fault.
        key: String,
        /// What is expected.
        message: String,
    },
    /// A dataset could not be loaded.
    #[error("{file}: {key}: {source}")]
    Dataset {
        /// The scene file.
        file: String,
        /// The dataset's key path.
        key: String,
        /// The loader's error (it names the data file).
        source: LoadError,
    },
}

// ---------------------------------------------------------------- the TOML schema

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneToml {
    datasets: Vec<DatasetToml>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "lowercase")]
enum TypeToml {
    U8,
    U16,
    I8,
    I16,
    F32,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "lowercase")]
enum EndianToml {
    Little,
    Big,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DatasetToml {
    name: String,
    builtin: Option<String>,
    size: Option<u32>,
    path: Option<PathBuf>,
    format: Option<Format>,
    dims: Option<[u32; 3]>,
    #[serde(rename = "type")]
    ty: Option<TypeToml>,
    endian: Option<EndianToml>,
    header_bytes: Option<u64>,
    spacing: Option<[f32; 3]>,
    views: Vec<ViewToml>,
}

#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum ModelToml {
    Voxel,
    #[default]
    Cell,
}

/// A view's `compositing`: a way's name, read by the kernel's [`Compositing::from_name`].
fn compositing<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Compositing, D::Error> {
    let name = String::deserialize(d)?;
    Compositing::from_name(&name).ok_or_else(|| {
        let names: Vec<String> = Compositing::ALL
            .iter()
            .map(|c| format!("`{}`", c.name()))
            .collect();
        serde::de::Error::custom(format!(
            "unknown compositing `{name}`, expected {}",
            names.join(" or ")
        ))
    })
}

/// A view's `accuracy`: a tier's name, read by the kernel's [`Accuracy::from_name`].
fn accuracy<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Accuracy, D::Error> {
    let name = String::deserialize(d)?;
    Accuracy::from_name(&name).ok_or_else(|| {
        let names: Vec<String> = Accuracy::ALL
            .iter()
            .map(|a| format!("`{}`", a.name()))
            .collect();
        serde::de::Error::custom(format!(
            "unknown tier `{name}`, expected {}",
            names.join(" or ")
        ))
    })
}

#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum ModeToml {
    #[default]
    Surfaces,
    Composite,
}

fn d_width() -> u32 {
    350
}
fn d_height() -> u32 {
    250
}
fn d_dt() -> f32 {
    0.5
}
fn d_one() -> f32 {
    1.0
}
fn d_true() -> bool {
    true
}
fn d_cutoff() -> f32 {
    DEFAULT_CUTOFF
}
fn d_depth() -> u8 {
    8
}
fn d_refine() -> u8 {
    2
}
fn d_count() -> u32 {
    1
}
fn d_white() -> [f32; 3] {
    [1.0; 3]
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ViewToml {
    name: Option<String>,
    #[serde(default = "d_width")]
    width: u32,
    #[serde(default = "d_height")]
    height: u32,
    #[serde(default)]
    model: ModelToml,
    #[serde(default = "d_dt")]
    dt: f32,
    #[serde(default = "d_one")]
    gradient_distance: f32,
    #[serde(default)]
    mode: ModeToml,
    #[serde(default, deserialize_with = "accuracy")]
    accuracy: Accuracy,
    #[serde(default, deserialize_with = "compositing")]
    compositing: Compositing,
    #[serde(default = "d_true")]
    shading: bool,
    #[serde(default)]
    lighting: LightingToml,
    #[serde(default)]
    background: [f32; 3],
    #[serde(default = "d_cutoff")]
    cutoff: f32,
    #[serde(default = "d_depth")]
    max_depth: u8,
    #[serde(default = "d_refine")]
    refine_steps: u8,
    #[serde(default = "d_count")]
    nodes: u32,
    #[serde(default = "d_count")]
    clusters: u32,
    #[serde(default)]
    balance: bool,
    #[serde(default)]
    camera: CameraToml,
    #[serde(default)]
    surfaces: Vec<SurfaceToml>,
    #[serde(default)]
    transfer: Vec<PointToml>,
    lights: Option<Vec<LightToml>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightingToml {
    ambient: f32,
    diffuse: f32,
    specular: f32,
    shininess: f32,
}

impl Default for LightingToml {
    fn default() -> Self {
        let s = Shading::default();
        LightingToml {
            ambient: s.ambient,
            diffuse: s.diffuse,
            specular: s.specular,
            shininess: s.shininess,
        }
    }
}

#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum ProjectionToml {
    #[default]
    Orthographic,
    Perspective,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraToml {
    #[serde(default)]
    projection: ProjectionToml,
    azimuth: Option<f32>,
    elevation: Option<f32>,
    distance: Option<f32>,
    eye: Option<[f32; 3]>,
    look_at: Option<[f32; 3]>,
    up: Option<[f32; 3]>,
    width: Option<f32>,
    fit: Option<f32>,
    fov: Option<f32>,
}

impl CameraToml {
    /// Whether the camera's scale is left to `fit`: an orthographic width or a perspective
    /// eye distance not given. Such a camera frames what the view can show, centred on it
    /// unless `look_at` says otherwise; a given width or eye keeps the volume's centre (the
    /// paper's framing of SOD is a width).
    fn frames_by_default(&self) -> bool {
        match self.projection {
            ProjectionToml::Orthographic => self.width.is_none(),
            ProjectionToml::Perspective => self.eye.is_none() && self.distance.is_none(),
        }
    }
}

/// What the host sets of a camera beyond its scene entry: the frame its default framing fits,
/// an orbit's turn, and, for every frame of an orbit, one target and scale.
#[derive(Clone, Copy, Debug, Default)]
struct CameraTweak {
    /// The box the default camera frames (the whole volume when `None`).
    frame: Option<Frame>,
    /// Degrees the eye turns about the up axis through the target.
    turn: f32,
    /// Target, overriding the frame's centre.
    look_at: Option<Vec3>,
    /// Orthographic width, overriding `fit`.
    width: Option<f32>,
    /// Perspective eye distance in radii, overriding `fit`.
    distance: Option<f32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SurfaceToml {
    iso: f32,
    #[serde(default = "d_white")]
    color: [f32; 3],
    #[serde(default)]
    transparency: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointToml {
    value: f32,
    color: [f32; 3],
    opacity: f32,
}

#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum LightTypeToml {
    Directional,
    Point,
}

#[derive(Debug, Clone, Copy, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum FrameToml {
    #[default]
    World,
    Camera,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightToml {
    #[serde(rename = "type")]
    ty: LightTypeToml,
    direction: Option<[f32; 3]>,
    position: Option<[f32; 3]>,
    #[serde(default = "d_white")]
    color: [f32; 3],
    #[serde(default = "d_one")]
    intensity: f32,
    #[serde(default)]
    shadows: bool,
    #[serde(default)]
    frame: FrameToml,
}

// ---------------------------------------------------------------- the checked scene

/// Where a dataset's samples come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// A built-in volume by name, on `size`³ samples where the scene gives a size.
    Builtin(String, Option<u32>),
    /// A raw file.
    Raw(PathBuf, RawLayout),
    /// A file whose header describes it (or a DICOM folder), in a known format, with the
    /// scene's spacing if it gives one.
    File(PathBuf, Format, Option<Vec3>),
}

/// A checked scene, datasets not yet loaded.
#[derive(Debug)]
pub struct Scene {
    /// The scene file's name, for messages.
    pub file: String,
    datasets: Vec<(DatasetToml, Source)>,
}

/// One view, ready to render.
#[derive(Debug)]
pub struct ViewJob {
    /// View name (unique within its dataset).
    pub name: String,
    /// The kernel view.
    pub view: View,
    /// Nodes of the hypercube the view renders on (`--nodes` overrides).
    pub nodes: u32,
    /// Clusters the nodes form (`--clusters` overrides).
    pub clusters: u32,
    /// Balance the slabs before rendering (the paper's static load balancing).
    pub balance: bool,
    /// The orbit this view is a frame of, if any.
    pub orbit: Option<OrbitFrame>,
}

/// One frame of an orbit around a view.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OrbitFrame {
    /// The view the orbit turns.
    pub view: String,
    /// This frame's index.
    pub frame: u32,
    /// Frames in the orbit.
    pub frames: u32,
}

/// A view turned by `turn` degrees, its default camera framing what it can show: `showing`,
/// summarised here the first time a view needs it (it depends on the view's classification,
/// not its camera, so the frames of an orbit share one).
fn framed_view(
    v: &ViewToml,
    volume: &Volume,
    turn: f32,
    look_at: Option<Vec3>,
    showing: &mut Option<Showing>,
) -> Result<View, (String, String)> {
    let base = CameraTweak {
        turn,
        look_at,
        ..CameraTweak::default()
    };
    let view = build_view(v, &volume.grid, &base)?;
    // Framing reads every sample: a window of the volume frames nothing.
    if !v.camera.frames_by_default() || !volume.is_whole() {
        return Ok(view);
    }
    let showing = showing.get_or_insert_with(|| Showing::of(volume, &view));
    match showing.frame(volume, &view) {
        Some(frame) => build_view(
            v,
            &volume.grid,
            &CameraTweak {
                frame: Some(frame),
                ..base
            },
        ),
        None => Ok(view),
    }
}

/// `frames` views turning once around `v`. A camera framed by default keeps one target (the
/// centre of what shows) and one scale (the largest any frame needs), so the volume turns in
/// place rather than swimming and breathing.
fn orbit_views(v: &ViewToml, volume: &Volume, frames: u32) -> Result<Vec<View>, (String, String)> {
    if frames == 0 || frames > 3600 {
        return Err((
            String::new(),
            format!("an orbit of {frames} frames: expected 1 to 3600"),
        ));
    }
    let turn = |i: u32| 360.0 * i as f32 / frames as f32;
    let c = &v.camera;
    let mut showing = None;
    let look_at = match (c.frames_by_default(), c.look_at) {
        (true, None) if volume.is_whole() => {
            let first = build_view(v, &volume.grid, &CameraTweak::default())?;
            let summary = showing.insert(Showing::of(volume, &first));
            summary.world_box(volume).map(|(lo, hi)| (lo + hi) * 0.5)
        }
        _ => None,
    };
    let views = (0..frames)
        .map(|i| framed_view(v, volume, turn(i), look_at, &mut showing))
        .collect::<Result<Vec<_>, _>>()?;
    let target = look_at.or(c.look_at.map(Vec3::from_array));
    let Some(target) = target.filter(|_| c.frames_by_default()) else {
        return Ok(views);
    };
    let (lo, hi) = volume.grid.world_box(views[0].spec().model);
    let radius = ((hi - lo).length() * 0.5).max(f32::MIN_POSITIVE);
    let (mut width, mut distance) = (0.0f32, 0.0f32);
    for view in &views {
        let camera = &view.spec().camera;
        match camera.projection() {
            Projection::Orthographic { width: w } => width = width.max(w),
            Projection::Perspective { .. } => {
                distance = distance.max((camera.eye() - target).length() / radius)
            }
        }
    }
    (0..frames)
        .map(|i| {
            let tweak = CameraTweak {
                turn: turn(i),
                look_at: Some(target),
                width: (width > 0.0).then_some(width),
                distance: (distance > 0.0).then_some(distance),
                frame: None,
            };
            build_view(v, &volume.grid, &tweak)
        })
        .collect()
}

/// Which X planes of a dataset a process needs, given its grid and views; `None` for all.
pub type Window<'a> = &'a dyn Fn(&Grid, &[ViewJob]) -> Option<Range<u32>>;

/// A dataset loaded, with its views built.
#[derive(Debug)]
pub struct DatasetJob {
    /// Dataset name.
    pub name: String,
    /// Where it came from, for reports.
    pub source: String,
    /// The samples.
    pub volume: Volume,
    /// Its views.
    pub views: Vec<ViewJob>,
}

fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
        && !s.starts_with('.')
}

impl Scene {
    /// Read and check a scene file.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            file: file.clone(),
            source,
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::parse(&text, &file, &base)
    }

    /// The built-in default scene.
    pub fn default_scene() -> Result<Scene, SceneError> {
        Scene::parse(DEFAULT_SCENE, "<built-in default scene>", Path::new("."))
    }

    /// Check scene text; relative paths resolve against `base`.
    pub fn parse(text: &str, file: &str, base: &Path) -> Result<Scene, SceneError> {
        let toml: SceneToml = toml::from_str(text).map_err(|e| SceneError::Parse {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let invalid = |key: String, message: String| SceneError::Invalid {
            file: file.to_string(),
            key,
            message,
        };
        if toml.datasets.is_empty() {
            return Err(invalid(
                "datasets".into(),
                "at least one [[datasets]] entry is needed".into(),
            ));
        }
        let mut datasets = Vec::new();
        for (i, d) in toml.datasets.into_iter().enumerate() {
            let key = format!("datasets[{i}]");
            if !valid_name(&d.name) {
                return Err(invalid(format!("{key}.name"), format!("\"{}\" must be 1-64 letters, digits, '-', '_' or '.', not starting with '.'", d.name)));
            }
            if datasets
                .iter()
                .any(|(o, _): &(DatasetToml, Source)| o.name == d.name)
            {
                return Err(invalid(
                    format!("{key}.name"),
                    format!(
                        "\"{}\" names two datasets; names must be unique (they name the images)",
                        d.name
                    ),
                ));
            }
            let source = source_of(&d, base).map_err(|(k, m)| invalid(format!("{key}.{k}"), m))?;
            if d.views.is_empty() {
                return Err(invalid(
                    format!("{key}.views"),
                    "each dataset needs at least one [[datasets.views]] entry".into(),
                ));
            }
            let mut names: Vec<String> = Vec::new();
            for (j, v) in d.views.iter().enumerate() {
                let name = view_name(v, j);
                if !valid_name(&name) {
                    return Err(invalid(
                        format!("{key}.views[{j}].name"),
                        format!("\"{name}\" must be 1-64 letters, digits, '-', '_' or '.'"),
                    ));
                }
                if names.contains(&name) {
                    return Err(invalid(
                        format!("{key}.views[{j}].name"),
                        format!("\"{name}\" names two views of this dataset"),
                    ));
                }
                names.push(name);
            }
            datasets.push((d, source));
        }
        Ok(Scene {
            file: file.to_string(),
            datasets,
        })
    }

    /// The same scene with every view in tier `tier`, whatever its `accuracy` says (the
    /// command line's `--accuracy`): set before any view is built, so each is built once.
    pub fn with_accuracy(mut self, tier: Accuracy) -> Scene {
        for (dataset, _) in &mut self.datasets {
            for view in &mut dataset.views {
                view.accuracy = tier;
            }
        }
        self
    }

    /// Every view's name, in order, without loading a dataset (as [`Scene::load`] names
    /// them, orbits aside).
    pub fn view_names(&self) -> Vec<String> {
        self.datasets
            .iter()
            .flat_map(|(d, _)| d.views.iter().enumerate().map(|(j, v)| view_name(v, j)))
            .collect()
    }

    /// Load every dataset and build every view; nothing is rendered yet.
    pub fn load(self) -> Result<Vec<DatasetJob>, SceneError> {
        self.load_orbits(None)
    }

    /// As [`Scene::load`], with every view turned into an orbit of `orbit` frames when given:
    /// views `<view>-000` … around the up axis through the target, at one scale.
    pub fn load_orbits(self, orbit: Option<u32>) -> Result<Vec<DatasetJob>, SceneError> {
        self.load_windowed(orbit, None)
    }

    /// Before any sample is read: `check` each dataset whose grid and sample type the scene
    /// gives (a built-in, a raw file; the file's length is checked too) with its views, on a
    /// volume of no planes, so that a dataset no machine holds is refused before it is
    /// generated or read. Views that would frame by what shows are checked as placed:
    /// framing reads samples, and what a node must hold does not depend on it.
    pub fn check_before_loading<E: From<SceneError>>(
        &self,
        orbit: Option<u32>,
        check: impl Fn(&str, &Volume, &[ViewJob]) -> Result<(), E>,
    ) -> Result<(), E> {
        for (i, (d, source)) in self.datasets.iter().enumerate() {
            let key = format!("datasets[{i}]");
            let failed = |e| source_error(&self.file, &key, e);
            if !streams(source).map_err(failed)? {
                continue;
            }
            let none = load_window(source, 0..0).map_err(failed)?;
            let views = dataset_views(d, &none, orbit, &self.file, &key)?;
            check(&d.name, &none, &views)?;
        }
        Ok(())
    }

    /// As [`Scene::load_orbits`], each dataset's samples only on the X planes `window` asks
    /// for given its grid and views, where that can be known without its samples: a built-in
    /// volume none of whose views frames its camera by what shows (a window is generated
    /// alone, never cut from the whole). Every other dataset is loaded whole.
    pub fn load_windowed(
        self,
        orbit: Option<u32>,
        window: Option<Window<'_>>,
    ) -> Result<Vec<DatasetJob>, SceneError> {
        let file = self.file;
        let mut jobs = Vec::new();
        for (i, (d, source)) in self.datasets.into_iter().enumerate() {
            let key = format!("datasets[{i}]");
            let failed = |e| source_error(&file, &key, e);
            let placed = d.views.iter().all(|v| !v.camera.frames_by_default());
            let windowed = match window.filter(|_| placed) {
                Some(window) => streams(&source).map_err(failed)?.then_some(window),
                None => None,
            };
            // Views that do not frame by what shows read the grid alone: built first on a
            // window of no planes, then the window they need is generated or streamed.
            let volume = match windowed {
                Some(_) => load_window(&source, 0..0).map_err(failed)?,
                None => load_source(&source).map_err(failed)?,
            };
            let views = dataset_views(&d, &volume, orbit, &file, &key)?;
            let volume = match windowed {
                Some(window) => {
                    let grid = volume.grid;
                    let planes = window(&grid, &views).unwrap_or(0..grid.dims()[0]);
                    load_window(&source, planes).map_err(failed)?
                }
                None => volume,
            };
            jobs.push(DatasetJob {
                name: d.name.clone(),
                source: describe(&source),
                volume,
                views,
            });
        }
        Ok(jobs)
    }
}

/// The views of dataset `d` (at `key` of the scene `file`) on `volume`, each turned into an
/// orbit of `orbit` frames when given.
fn dataset_views(
    d: &DatasetToml,
    volume: &Volume,
    orbit: Option<u32>,
    file: &str,
    key: &str,
) -> Result<Vec<ViewJob>, SceneError> {
    let mut views = Vec::new();
    for (j, v) in d.views.iter().enumerate() {
        let vkey = format!("{key}.views[{j}]");
        let invalid = |(k, message): (String, String)| SceneError::Invalid {
            file: file.to_string(),
            key: if k.is_empty() {
                vkey.clone()
            } else {
                format!("{vkey}.{k}")
            },
            message,
        };
        let name = view_name(v, j);
        let frames = match orbit {
            None => vec![framed_view(v, volume, 0.0, None, &mut None).map_err(invalid)?],
            Some(n) => orbit_views(v, volume, n).map_err(invalid)?,
        };
        let count = frames.len() as u32;
        for (i, view) in frames.into_iter().enumerate() {
            let (name, orbit) = match orbit {
                None => (name.clone(), None),
                Some(_) => (
                    format!("{name}-{i:03}"),
                    Some(OrbitFrame {
                        view: name.clone(),
                        frame: i as u32,
                        frames: count,
                    }),
                ),
            };
            views.push(ViewJob {
                name,
                view,
                nodes: v.nodes,
                clusters: v.clusters,
                balance: v.balance,
                orbit,
            });
        }
    }
    Ok(views)
}

/// A dataset's source that failed to load, as the scene names it.
fn source_error(file: &str, key: &str, e: SourceError) -> SceneError {
    match e {
        SourceError::Load(source) => SceneError::Dataset {
            file: file.to_string(),
            key: key.to_string(),
            source,
        },
        SourceError::Builtin(m) => SceneError::Invalid {
            file: file.to_string(),
            key: format!("{key}.builtin"),
            message: m,
        },
    }
}

fn view_name(v: &ViewToml, index: usize) -> String {
    v.name.clone().unwrap_or_else(|| format!("view{index}"))
}

fn describe(source: &Source) -> String {
    match source {
        Source::Builtin(n, None) => format!("builtin:{n}"),
        Source::Builtin(n, Some(size)) => format!("builtin:{n} ({size}³)"),
        Source::Raw(p, _) | Source::File(p, _, _) => p.display().to_string(),
    }
}

/// Work out where a dataset comes from; errors are `(key, message)`.
fn source_of(d: &DatasetToml, base: &Path) -> Result<Source, (String, String)> {
    let spacing = d.spacing.map(Vec3::from_array);
    if let Some(s) = spacing {
        if !(s.is_finite() && s.min_element() > 0.0) {
            return Err((
                "spacing".into(),
                format!(
                    "{:?} must be three finite numbers > 0",
                    d.spacing.unwrap_or_default()
                ),
            ));
        }
    }
    let raw_only = [
        ("dims", d.dims.is_some()),
        ("type", d.ty.is_some()),
        ("endian", d.endian.is_some()),
        ("header_bytes", d.header_bytes.is_some()),
    ];
    match (&d.builtin, &d.path) {
        (Some(_), Some(_)) => Err((
            "builtin".into(),
            "give either builtin or path, not both".into(),
        )),
        (None, None) => Err((
            "path".into(),
            format!(
                "a dataset needs a path or a builtin ({})",
                builtin::NAMES.join(", ")
            ),
        )),
        (Some(name), None) => {
            if let Some((k, _)) = raw_only.iter().find(|(_, set)| *set) {
                return Err((
                    (*k).into(),
                    "applies to raw files, not built-in volumes".into(),
                ));
            }
            if d.format.is_some() || d.spacing.is_some() {
                return Err((
                    "builtin".into(),
                    "built-in volumes take no format or spacing".into(),
                ));
            }
            if !builtin::NAMES.contains(&name.as_str()) {
                return Err((
                    "builtin".into(),
                    format!(
                        "unknown built-in \"{name}\"; expected one of {}",
                        builtin::NAMES.join(", ")
                    ),
                ));
            }
            if let Some(size) = d.size {
                let n = u64::from(size);
                if size < builtin::MIN_SIZE {
                    return Err((
                        "size".into(),
                        format!(
                            "size is {size}; a built-in needs at least {} samples a side",
                            builtin::MIN_SIZE
                        ),
                    ));
                }
                if let Err(e) = formats::declared_samples(&[n, n, n]) {
                    return Err(("size".into(), format!("size {size}: {e}")));
                }
            }
            Ok(Source::Builtin(name.clone(), d.size))
        }
        (None, Some(_)) if d.size.is_some() => Err((
            "size".into(),
            "applies to built-in volumes; a file's header (or a raw file's dims) gives its shape"
                .into(),
        )),
        (None, Some(p)) => {
            let path = base.join(p);
            let raw_keys = raw_only.iter().any(|(_, set)| *set);
            let format = match d.format {
                Some(f) => f,
                None => match Format::from_extension(&path) {
                    Some(f) => f,
                    None if raw_keys => Format::Raw,
                    None => Format::sniff(&path).ok_or_else(|| {
                        (
                            "format".to_string(),
                            format!(
                                "cannot tell the format of {} from its name or first bytes: give format ({}), or dims and type for a raw file",
                                path.display(),
                                Format::NAMES
                            ),
                        )
                    })?,
                },
            };
            match format {
                Format::Raw => {
                    let dims = d.dims.ok_or((
                        "dims".to_string(),
                        "a raw dataset needs dims = [nx, ny, nz]".to_string(),
                    ))?;
                    let ty = d.ty.ok_or((
                        "type".to_string(),
                        "a raw dataset needs type (u8, u16, i8, i16, f32)".to_string(),
                    ))?;
                    let ty = match ty {
                        TypeToml::U8 => FileType::U8,
                        TypeToml::U16 => FileType::U16,
                        TypeToml::I8 => FileType::I8,
                        TypeToml::I16 => FileType::I16,
                        TypeToml::F32 => FileType::F32,
                    };
                    let endian =
                        match d.endian {
                            Some(EndianToml::Big) => Endian::Big,
                            Some(EndianToml::Little) => Endian::Little,
                            None if ty.bytes() == 1 => Endian::Little,
                            None => return Err((
                                "endian".into(),
                                "a raw dataset of multi-byte samples needs endian (little or big)"
                                    .into(),
                            )),
                        };
                    if let Some(axis) = dims.iter().position(|&n| n == 0) {
                        return Err((
                            "dims".into(),
                            format!("dims[{axis}] is 0; every dimension must be at least 1"),
                        ));
                    }
                    let layout = RawLayout {
                        dims,
                        ty,
                        endian,
                        header_bytes: d.header_bytes.unwrap_or(0),
                        spacing: spacing.unwrap_or(Vec3::ONE),
                        trailing: false,
                    };
                    Ok(Source::Raw(path, layout))
                }
                other => {
                    if let Some((k, _)) = raw_only.iter().find(|(_, set)| *set) {
                        return Err((
                            (*k).into(),
                            "applies to raw files; this file's header gives it".into(),
                        ));
                    }
                    Ok(Source::File(path, other, spacing))
                }
            }
        }
    }
}

enum SourceError {
    Load(LoadError),
    Builtin(String),
}

fn load_source(source: &Source) -> Result<Volume, SourceError> {
    match source {
        Source::Builtin(name, size) => builtin::volume(name, *size)
            .ok_or_else(|| SourceError::Builtin(format!("unknown built-in \"{name}\""))),
        Source::Raw(p, layout) => formats::raw::load(p, layout).map_err(SourceError::Load),
        Source::File(p, f, s) => formats::load(p, *f, *s).map_err(SourceError::Load),
    }
}

/// Whether `source`'s X planes are had alone, without the others ([`load_window`]): a
/// built-in's, a raw file's, a NRRD file's with raw samples.
fn streams(source: &Source) -> Result<bool, SourceError> {
    match source {
        Source::Builtin(..) | Source::Raw(..) => Ok(true),
        Source::File(p, f, s) => formats::streams(p, *f, *s).map_err(SourceError::Load),
    }
}

/// Of `source`, the X planes `planes` alone where it [`streams`]: a built-in's generated, a
/// raw file's or NRRD file's streamed; another file whole.
fn load_window(source: &Source, planes: Range<u32>) -> Result<Volume, SourceError> {
    match source {
        Source::Builtin(name, size) => builtin::window(name, *size, planes.clone())
            .ok_or_else(|| SourceError::Builtin(format!("planes {planes:?} of \"{name}\""))),
        Source::Raw(p, layout) => {
            formats::raw::load_window(p, layout, planes).map_err(SourceError::Load)
        }
        Source::File(p, f, s) => formats::load_window(p, *f, *s, planes).map_err(SourceError::Load),
    }
}

fn finite3(key: &str, v: [f32; 3]) -> Result<Vec3, (String, String)> {
    let v3 = Vec3::from_array(v);
    if v3.is_finite() {
        Ok(v3)
    } else {
        Err((key.into(), format!("{v:?} must be finite")))
    }
}

fn unit_color(key: &str, v: [f32; 3]) -> Result<Vec3, (String, String)> {
    if v.iter().all(|c| (0.0..=1.0).contains(c)) {
        Ok(Vec3::from_array(v))
    } else {
        Err((
            key.into(),
            format!("{v:?}: each channel must lie in [0, 1]"),
        ))
    }
}

/// The camera of a view. `frame` is the box the default camera frames (the cells the view
/// can show, or the whole volume): its centre is the default target, and `fit` fills the
/// image with its projection. Eye distances are in radii of the whole volume's bounding
/// sphere, so an orbiting eye stays outside the volume whatever it frames.
fn build_camera(
    c: &CameraToml,
    grid: &Grid,
    model: Model,
    tweak: &CameraTweak,
    aspect: f32,
) -> Result<Camera, (String, String)> {
    let frame = &tweak
        .frame
        .unwrap_or_else(|| Frame::of_box(grid.world_box(model)));
    let (lo, hi) = grid.world_box(model);
    let radius = ((hi - lo).length() * 0.5).max(f32::MIN_POSITIVE);
    let orbit = c.azimuth.is_some() || c.elevation.is_some() || c.distance.is_some();
    if orbit && c.eye.is_some() {
        return Err((
            "camera.eye".into(),
            "give either eye (with look_at, up) or azimuth/elevation/distance, not both".into(),
        ));
    }
    let perspective = c.projection == ProjectionToml::Perspective;
    if perspective && c.width.is_some() {
        return Err((
            "camera.width".into(),
            "width applies to orthographic cameras; a perspective camera takes fov (and fit)"
                .into(),
        ));
    }
    if !perspective && c.fov.is_some() {
        return Err((
            "camera.fov".into(),
            "fov applies to perspective cameras; an orthographic camera takes width or fit".into(),
        ));
    }
    if c.width.is_some() && c.fit.is_some() {
        return Err((
            "camera.fit".into(),
            "give either width or fit, not both".into(),
        ));
    }
    let fit = c.fit.unwrap_or(0.86);
    if !(fit > 0.0 && fit <= 10.0) {
        return Err((
            "camera.fit".into(),
            format!("{fit} must lie in (0, 10]: the share of the image the volume fills"),
        ));
    }
    let up = finite3("camera.up", c.up.unwrap_or([0.0, 1.0, 0.0]))?;
    let centre = frame.centre;
    let target = match tweak.look_at {
        Some(t) => t,
        None => finite3("camera.look_at", c.look_at.unwrap_or(centre.to_array()))?,
    };
    let fov = c.fov.unwrap_or(30.0);
    if !(fov > 0.0 && fov < 180.0) {
        return Err((
            "camera.fov".into(),
            format!("{fov} must lie in (0, 180) degrees"),
        ));
    }
    let (eye, toward_eye) = match c.eye {
        Some(e) => {
            let e = finite3("camera.eye", e)?;
            (e, e - target)
        }
        None => {
            let az = c.azimuth.unwrap_or(45.0).to_radians();
            let el = c.elevation.unwrap_or(0.0);
            if !(-90.0..=90.0).contains(&el) {
                return Err((
                    "camera.elevation".into(),
                    format!("{el} must lie in [-90, 90] degrees"),
                ));
            }
            let el = el.to_radians();
            let distance =
                tweak
                    .distance
                    .or(c.distance)
                    .unwrap_or(if perspective { 3.0 } else { 2.0 });
            if !(distance.is_finite() && distance > 0.0) {
                return Err((
                    "camera.distance".into(),
                    format!("{distance} must be > 0 (in bounding-sphere radii)"),
                ));
            }
            let toward_eye = Vec3::new(
                libm::sinf(az) * libm::cosf(el),
                libm::sinf(el),
                libm::cosf(az) * libm::cosf(el),
            );
            (target + toward_eye * (distance * radius), toward_eye)
        }
    };
    // An orbit's frame: the eye turned about the up axis through the target.
    let turn = glam::Quat::from_axis_angle(up.normalize_or(Vec3::Y), tweak.turn.to_radians());
    let (eye, toward_eye) = (target + turn * (eye - target), turn * toward_eye);
    let projection = if perspective {
        Projection::Perspective {
            fov_y: fov.to_radians(),
        }
    } else {
        Projection::Orthographic { width: 1.0 }
    };
    let cam = Camera::look_at(eye, target, up, projection)
        .map_err(|e| ("camera".to_string(), e.to_string()))?;
    let (right, image_up) = cam.image_axes();
    let corners = frame.corners.map(|p| p - target);
    if perspective {
        if c.eye.is_some() || c.distance.is_some() || tweak.distance.is_some() {
            return Ok(cam);
        }
        // The nearest eye on the orbit from which every corner of the frame lies inside
        // `fit` of the image: a corner at depth d - p·t beside the axis by |p·up| needs
        // d >= p·t + |p·up| / (fit·tan(fov/2)) (and likewise across, with the aspect).
        let dir = toward_eye.normalize_or_zero();
        let t = fit * libm::tanf(fov.to_radians() * 0.5);
        let distance = corners
            .iter()
            .map(|p| {
                p.dot(dir) + (p.dot(image_up).abs() / t).max(p.dot(right).abs() / (t * aspect))
            })
            .fold(f32::MIN_POSITIVE, f32::max);
        return Camera::look_at(target + dir * distance, target, up, projection)
            .map_err(|e| ("camera".to_string(), e.to_string()));
    }
    let width = match tweak.width.or(c.width) {
        Some(w) => {
            if !(w.is_finite() && w > 0.0) {
                return Err((
                    "camera.width".into(),
                    format!("{w} must be > 0 (world units)"),
                ));
            }
            w
        }
        None => {
            // The width at which the frame's projection fills `fit` of the image in its
            // tighter direction. The paper's own framing of SOD is `width = 175` (2 pixels
            // per grid unit: its voxels cover 301×194 of 350×250).
            let (mut w, mut h) = (0.0f32, 0.0f32);
            for p in corners {
                w = w.max(2.0 * p.dot(right).abs());
                h = h.max(2.0 * p.dot(image_up).abs());
            }
            (w.max(h * aspect) / fit).max(f32::MIN_POSITIVE)
        }
    };
    Camera::look_at(eye, target, up, Projection::Orthographic { width })
        .map_err(|e| ("camera".to_string(), e.to_string()))
}

/// Build a view; its default camera frames `frame` (the whole volume when `None`).
fn build_view(v: &ViewToml, grid: &Grid, tweak: &CameraTweak) -> Result<View, (String, String)> {
    if v.width == 0 || v.height == 0 || v.width > 16384 || v.height > 16384 {
        return Err((
            "width".into(),
            format!(
                "{}x{} must be between 1x1 and 16384x16384 pixels",
                v.width, v.height
            ),
        ));
    }
    for (key, n) in [("nodes", v.nodes), ("clusters", v.clusters)] {
        if !n.is_power_of_two() || n > 1024 {
            return Err((
                key.into(),
                format!("{n} must be a power of two from 1 to 1024"),
            ));
        }
    }
    if v.clusters > v.nodes {
        return Err((
            "clusters".into(),
            format!(
                "{} clusters cannot be made of {} nodes",
                v.clusters, v.nodes
            ),
        ));
    }
    let model = match v.model {
        ModelToml::Cell => Model::Cell,
        ModelToml::Voxel => Model::Voxel,
    };
    if let (Model::Cell, Some(axis)) = (model, grid.dims().iter().position(|&n| n < 2)) {
        return Err((
            "model".into(),
            format!(
                "the cell model interpolates between samples and needs at least 2 along each axis; this volume has 1 along {}: use model = \"voxel\"",
                ["x", "y", "z"][axis]
            ),
        ));
    }
    let camera = build_camera(
        &v.camera,
        grid,
        model,
        tweak,
        v.width as f32 / v.height as f32,
    )?;
    let mode = match v.mode {
        ModeToml::Surfaces => {
            if !v.transfer.is_empty() {
                return Err((
                    "transfer".into(),
                    "a transfer function applies to mode = \"composite\"".into(),
                ));
            }
            if v.surfaces.len() > MAX_SURFACES {
                return Err((
                    "surfaces".into(),
                    format!("{} surfaces; at most {MAX_SURFACES}", v.surfaces.len()),
                ));
            }
            let mut surfaces = voxcube_kernel::heapless::Vec::new();
            for (i, s) in v.surfaces.iter().enumerate() {
                let color = unit_color(&format!("surfaces[{i}].color"), s.color)?;
                if !(0.0..=1.0).contains(&s.transparency) {
                    return Err((
                        format!("surfaces[{i}].transparency"),
                        format!("{} must lie in [0, 1] (0 is opaque)", s.transparency),
                    ));
                }
                if !s.iso.is_finite() {
                    return Err((format!("surfaces[{i}].iso"), "must be finite".into()));
                }
                // Capacity checked above.
                let _ = surfaces.push(IsoSurface {
                    iso: s.iso,
                    color,
                    transparency: s.transparency,
                });
            }
            Mode::Surfaces(surfaces)
        }
        ModeToml::Composite => {
            if !v.surfaces.is_empty() {
                return Err((
                    "surfaces".into(),
                    "iso-surfaces apply to mode = \"surfaces\"".into(),
                ));
            }
            let points: Vec<ControlPoint> = v
                .transfer
                .iter()
                .map(|p| ControlPoint {
                    value: p.value,
                    color: Vec3::from_array(p.color),
                    opacity: p.opacity,
                })
                .collect();
            Mode::Composite(
                TransferFunction::new(&points)
                    .map_err(|e| ("transfer".to_string(), e.to_string()))?,
            )
        }
    };
    let shading = v.shading.then_some(Shading {
        ambient: v.lighting.ambient,
        diffuse: v.lighting.diffuse,
        specular: v.lighting.specular,
        shininess: v.lighting.shininess,
    });
    let (right, up) = camera.image_axes();
    let forward = camera.forward();
    let to_world = |frame: FrameToml, d: Vec3| match frame {
        FrameToml::World => d,
        FrameToml::Camera => right * d.x + up * d.y + forward * d.z,
    };
    let mut lights = voxcube_kernel::heapless::Vec::<Light, MAX_LIGHTS>::new();
    match &v.lights {
        None => {
            // One light from the viewer's upper left, so a scene that names none is still lit.
            let dir = forward - up * 0.5 + right * 0.4;
            let _ = lights.push(
                Light::directional(dir, Vec3::ONE, false)
                    .map_err(|e| ("lights".to_string(), e.to_string()))?,
            );
        }
        Some(ls) => {
            if ls.len() > MAX_LIGHTS {
                return Err((
                    "lights".into(),
                    format!("{} lights; at most {MAX_LIGHTS}", ls.len()),
                ));
            }
            for (i, l) in ls.iter().enumerate() {
                let key = format!("lights[{i}]");
                if !(l.intensity.is_finite() && l.intensity >= 0.0) {
                    return Err((
                        format!("{key}.intensity"),
                        format!("{} must be finite and >= 0", l.intensity),
                    ));
                }
                let color = finite3(&format!("{key}.color"), l.color)? * l.intensity;
                let light = match l.ty {
                    LightTypeToml::Directional => {
                        if l.position.is_some() {
                            return Err((
                                format!("{key}.position"),
                                "a directional light has a direction, not a position".into(),
                            ));
                        }
                        let d = l.direction.ok_or((format!("{key}.direction"), "a directional light needs direction = [x, y, z] (the way light travels)".to_string()))?;
                        Light::directional(
                            to_world(l.frame, finite3(&format!("{key}.direction"), d)?),
                            color,
                            l.shadows,
                        )
                    }
                    LightTypeToml::Point => {
                        if l.direction.is_some() {
                            return Err((
                                format!("{key}.direction"),
                                "a point light has a position, not a direction".into(),
                            ));
                        }
                        let p = l.position.ok_or((
                            format!("{key}.position"),
                            "a point light needs position = [x, y, z]".to_string(),
                        ))?;
                        let p = finite3(&format!("{key}.position"), p)?;
                        let p = match l.frame {
                            FrameToml::World => p,
                            FrameToml::Camera => camera.eye() + to_world(FrameToml::Camera, p),
                        };
                        Light::point(p, color, l.shadows)
                    }
                };
                let light = light.map_err(|e| (key.clone(), e.to_string()))?;
                let _ = lights.push(light);
            }
        }
    }
    let accuracy = v.accuracy;
    let spec = ViewSpec {
        width: v.width,
        height: v.height,
        camera,
        model,
        dt: v.dt,
        gradient_distance: v.gradient_distance,
        mode,
        shading,
        lights,
        background: unit_color("background", v.background)?,
        cutoff: v.cutoff,
        max_depth: v.max_depth,
        refine_steps: v.refine_steps,
        accuracy,
        compositing: v.compositing,
    };
    View::new(spec, grid).map_err(|e| (String::new(), e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_are_named_as_loading_names_them_without_reading_a_dataset() {
        let text = r#"
[[datasets]]
name = "m"
builtin = "molecule"
[[datasets.views]]
name = "first"
mode = "composite"
[[datasets.views.transfer]]
value = 50.0
color = [1.0, 1.0, 1.0]
opacity = 0.5
[[datasets.views]]
[[datasets.views.surfaces]]
iso = 40.0
[[datasets]]
name = "absent"
path = "no-such-volume.raw"
format = "raw"
dims = [4, 4, 4]
type = "u8"
[[datasets.views]]
name = "last"
[[datasets.views.surfaces]]
iso = 1.0
"#;
        let scene = Scene::parse(text, "names.toml", Path::new(".")).unwrap();
        assert_eq!(scene.view_names(), ["first", "view1", "last"]);
        // Loading reads the second dataset's file, which is not there.
        let e = scene.load().unwrap_err().to_string();
        assert!(e.contains("no-such-volume.raw"), "{e}");
        // Where every dataset loads, the names are the loaded views'.
        let one = &text[..text.find("[[datasets]]\nname = \"absent\"").unwrap()];
        let scene = Scene::parse(one, "names.toml", Path::new(".")).unwrap();
        let names = scene.view_names();
        let loaded: Vec<String> = scene.load().unwrap()[0]
            .views
            .iter()
            .map(|v| v.name.clone())
            .collect();
        assert_eq!(names, loaded);
    }
}
