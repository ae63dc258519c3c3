//! `docs/default-scene.png`, the picture the README opens with, is what `voxcube render` draws
//! for the built-in default scene today. When a change of the image definition moves it,
//! regenerate it as docs/renderer.md says:
//! `cargo run --release -- render -o target/default-scene` and copy
//! `target/default-scene/molecule-paper.png` over `docs/default-scene.png`.

use voxcube::input::scene::Scene;
use voxcube::run::render::render;

/// Pixels that differ between two RGBA8 buffers of the same size.
fn differing(a: &[u8], b: &[u8]) -> usize {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(x, y)| x != y)
        .count()
}

#[test]
fn the_readme_picture_is_what_render_draws_today() {
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("the default scene loads");
    let job = &jobs[0];
    let rendered = render(&job.volume, &job.views[0].view).expect("renders");
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/default-scene.png");
    let png = image::open(path)
        .expect("docs/default-scene.png")
        .to_rgba8();
    assert_eq!(
        (png.width(), png.height()),
        (rendered.width, rendered.height),
        "docs/default-scene.png has another size than the default scene's view"
    );
    let drawn = rendered.bytes();
    let differ = differing(png.as_raw(), &drawn);
    assert_eq!(
        differ, 0,
        "{differ} pixels of docs/default-scene.png differ from today's render: regenerate it"
    );
    // Control: one changed channel of one pixel is caught.
    let mut changed = drawn.clone();
    changed[4 * 1000] ^= 1;
    assert_eq!(differing(png.as_raw(), &changed), 1);
}
