//! The paper's dataset and view as the experiments write them into scene text, once: SOD's
//! raw layout, the paper's view as a shaded surface, and SOD's transfer function for its
//! composited views. `scenes/sod.toml` states the same for `voxcube render`; a test keeps
//! the two equal.

use std::path::Path;

/// SOD's file name in the shared data folder.
pub const SOD_FILE: &str = "sod-97x97x116.u8.binary";

/// The iso value of SOD's surface in the paper's view.
pub const SOD_ISO: &str = "50.0";

/// The dataset lines that read SOD from `file` (the raw file with its 12-byte header: three
/// little-endian u32, 97, 97, 116).
pub fn sod_source(file: &Path) -> String {
    format!(
        "path = \"{}\"\nformat = \"raw\"\ndims = [97, 97, 116]\ntype = \"u8\"\nheader_bytes = 12",
        file.display().to_string().replace('\\', "/")
    )
}

/// The paper's view as a shaded surface, named NAME, with its placeholders: WIDTH × HEIGHT
/// pixels, step DT, SPAN grid units across, iso value ISO.
pub const SURFACE_VIEW: &str = r#"
[[datasets.views]]
name = "NAME"
width = WIDTH
height = HEIGHT
dt = DT
[datasets.views.camera]
azimuth = 45.0
elevation = 0.0
width = SPAN
[[datasets.views.surfaces]]
iso = ISO
color = [0.95, 0.78, 0.45]
[[datasets.views.lights]]
type = "directional"
direction = [0.4, -0.5, 1.0]
frame = "camera"
"#;

/// `views` (with [`SURFACE_VIEW`]'s placeholders) at `width` × `height` pixels, step `dt`,
/// `span` grid units across; the name and the iso value still to fill.
pub fn sized(views: &str, width: u32, height: u32, dt: f64, span: f32) -> String {
    // DT last: WIDTH holds it.
    views
        .replace("SPAN", &format!("{span:.1}"))
        .replace("WIDTH", &width.to_string())
        .replace("HEIGHT", &height.to_string())
        .replace("DT", &format!("{dt:?}"))
}

/// The paper's view at the paper's size (350 × 250, Δt = ½, 175 grid units across), named
/// NAME, iso value ISO still to fill.
pub fn paper_surface_view() -> String {
    sized(SURFACE_VIEW, 350, 250, 0.5, 175.0)
}

/// The paper's view composited, named NAME, in the accuracy tier TIER, shaded or not
/// (SHADING), with [`SURFACE_VIEW`]'s size placeholders and without lights (a scene's default
/// light).
const COMPOSITE_VIEW: &str = r#"
[[datasets.views]]
name = "NAME"
width = WIDTH
height = HEIGHT
dt = DT
mode = "composite"
accuracy = "TIER"
shading = SHADING
[datasets.views.camera]
azimuth = 45.0
width = SPAN
"#;

/// The paper's view composited with [`COMPOSITE_TRANSFER`], named `name`, in accuracy tier
/// `tier`, shaded or not, its size placeholders still to fill ([`sized`]).
pub fn composite(name: &str, tier: &str, shading: bool) -> String {
    composite_through(name, tier, shading, COMPOSITE_TRANSFER)
}

/// [`composite`] with the transfer function `transfer` (its `[[datasets.views.transfer]]`
/// entries) instead of SOD's.
pub fn composite_through(name: &str, tier: &str, shading: bool, transfer: &str) -> String {
    COMPOSITE_VIEW
        .replace("NAME", name)
        .replace("TIER", tier)
        .replace("SHADING", &shading.to_string())
        + transfer
}

/// SOD's transfer function, for every composited view of it the experiments take.
pub const COMPOSITE_TRANSFER: &str = r#"[[datasets.views.transfer]]
value = 10.0
color = [0.2, 0.3, 0.8]
opacity = 0.0
[[datasets.views.transfer]]
value = 60.0
color = [0.9, 0.7, 0.3]
opacity = 0.15
[[datasets.views.transfer]]
value = 200.0
color = [1.0, 0.2, 0.1]
opacity = 0.8
"#;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::{DatasetJob, Scene};

    /// `scenes/sod.toml` with the built-in molecule (SOD's grid) in SOD's place, so that the
    /// views build without the shared data.
    fn shipped() -> DatasetJob {
        let text = include_str!("../../../scenes/sod.toml");
        let start = text.find("path = ").expect("sod.toml reads SOD by path");
        let end = text
            .find("\n\n[[datasets.views]]")
            .expect("sod.toml has views");
        let text = format!("{}builtin = \"molecule\"{}", &text[..start], &text[end..]);
        Scene::parse(&text, "scenes/sod.toml", Path::new("."))
            .and_then(Scene::load)
            .expect("scenes/sod.toml parses")
            .remove(0)
    }

    fn ours(views: &str) -> DatasetJob {
        let text = format!("[[datasets]]\nname = \"sod\"\nbuiltin = \"molecule\"\n{views}");
        Scene::parse(&text, "<experiments' SOD>", Path::new("."))
            .and_then(Scene::load)
            .expect("the experiments' views parse")
            .remove(0)
    }

    #[test]
    fn the_experiments_views_of_sod_are_the_shipped_scene_s() {
        let shipped = shipped();
        let spec = |job: &DatasetJob, name: &str| {
            let view = job.views.iter().find(|v| v.name == name).expect(name);
            view.view.spec().clone()
        };
        let surface = ours(
            &paper_surface_view()
                .replace("NAME", "paper")
                .replace("ISO", SOD_ISO),
        );
        assert_eq!(spec(&surface, "paper"), spec(&shipped, "paper"));
        let composite = ours(&format!(
            "[[datasets.views]]\nname = \"composite\"\ndt = 0.5\nmode = \"composite\"\n\
             [datasets.views.camera]\nazimuth = 45.0\nwidth = 175.0\n{COMPOSITE_TRANSFER}"
        ));
        assert_eq!(spec(&composite, "composite"), spec(&shipped, "composite"));
        // Negative control: another iso value is another view.
        let other = ours(
            &paper_surface_view()
                .replace("NAME", "paper")
                .replace("ISO", "51.0"),
        );
        assert_ne!(spec(&other, "paper"), spec(&shipped, "paper"));
    }
}
