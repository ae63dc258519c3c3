//! Effects on demand: no ray is created and no work is done for an effect the scene does not
//! call for. Each assertion of "zero" is paired with a control showing the same scene with the
//! effect on does the work, so the counters are known to count.

use voxcube::input::scene::Scene;
use voxcube_kernel::counters::Counters;
use voxcube_tests::trace_all;

/// Render the single view of a scene over the built-in molecule; its counters.
fn counters(view_toml: &str) -> Counters {
    let text = format!(
        "[[datasets]]\nname = \"m\"\nbuiltin = \"molecule\"\n[[datasets.views]]\nwidth = 48\nheight = 36\n{view_toml}"
    );
    let jobs = Scene::parse(&text, "test", std::path::Path::new("."))
        .and_then(Scene::load)
        .expect("valid scene");
    let job = &jobs[0];
    trace_all(&job.volume, &job.views[0].view).1
}

const OPAQUE: &str = "[[datasets.views.surfaces]]\niso = 40.0\n";
const SEMI: &str = "[[datasets.views.surfaces]]\niso = 40.0\ntransparency = 0.5\n";
const PLAIN_LIGHT: &str = "[[datasets.views.lights]]\ntype = \"directional\"\ndirection = [0.3, -0.5, 1.0]\nframe = \"camera\"\n";
const SHADOW_LIGHT: &str =
    "[[datasets.views.lights]]\ntype = \"directional\"\ndirection = [0.3, -0.5, 1.0]\nframe = \"camera\"\nshadows = true\n";

#[test]
fn no_shadow_lights_means_no_shadow_rays() {
    let off = counters(&format!("{OPAQUE}{PLAIN_LIGHT}"));
    assert_eq!(off.shadow_rays, 0);
    let on = counters(&format!("{OPAQUE}{SHADOW_LIGHT}"));
    assert!(
        on.shadow_rays > 0,
        "control: a shadow light traces shadow rays"
    );
    assert_eq!(on.primary_rays, off.primary_rays);
}

#[test]
fn opaque_surfaces_mean_no_transparency_rays() {
    let off = counters(&format!("{OPAQUE}{PLAIN_LIGHT}"));
    assert_eq!(off.transparency_rays, 0);
    let on = counters(&format!("{SEMI}{PLAIN_LIGHT}"));
    assert!(
        on.transparency_rays > 0,
        "control: a semi-transparent surface traces transparency rays"
    );
}

#[test]
fn no_shading_means_no_gradients_and_no_shadow_rays() {
    let off = counters(&format!("shading = false\n{SEMI}{SHADOW_LIGHT}"));
    assert_eq!((off.gradients, off.shadings, off.shadow_rays), (0, 0, 0));
    let on = counters(&format!("{SEMI}{SHADOW_LIGHT}"));
    assert!(on.gradients > 0 && on.shadings > 0);
}

#[test]
fn voxel_model_does_no_interpolation_and_compositing_no_surface_search() {
    let voxel = counters(&format!("model = \"voxel\"\n{OPAQUE}"));
    assert_eq!(voxel.interpolations, 0);
    assert!(voxel.lookups > 0);
    let transfer = "mode = \"composite\"\nshading = false\n[[datasets.views.transfer]]\nvalue = 0.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.0\n[[datasets.views.transfer]]\nvalue = 255.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.5\n";
    let composite = counters(transfer);
    assert_eq!(
        (
            composite.crossings,
            composite.refinements,
            composite.gradients
        ),
        (0, 0, 0)
    );
    assert!(composite.samples > 0);
}
