//! The figures docs/porting.md quotes, recomputed so the document cannot drift from the code.

use voxcube_kernel::node::flow;

#[test]
fn porting_md_memory_map_figures_hold() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/porting.md"))
        .expect("docs/porting.md");
    let buffer = flow::buffer_bytes(16, 8);
    assert!(
        text.contains(&format!("{buffer} bytes")),
        "docs/porting.md must quote the 16-node, i_max 8 receive buffer: {buffer} bytes"
    );
    let worker = voxcube::memory::budget::worker_bytes();
    assert!(
        text.contains(&format!("{worker} bytes")),
        "docs/porting.md must quote the simulator worker's size: {worker} bytes"
    );
    // The board example's worker: queues of 8, 16 records, an outbox of 8, a ring of 2.
    let board = size_of::<voxcube_kernel::node::worker::Worker<'static, u8, 8, 16, 8, 2>>();
    let board = format!("{},{:03}", board / 1000, board % 1000);
    assert!(
        text.contains(&format!("{board} in the board example's")),
        "docs/porting.md must quote the board example worker's size: {board}"
    );
}

#[test]
fn porting_md_slab_figure_holds() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/porting.md"))
        .expect("docs/porting.md");
    let grid = voxcube_kernel::volume::grid::Grid::new([97, 97, 116], voxcube_kernel::Vec3::ONE)
        .expect("grid");
    // The paper's view: a parallel projection without shadows, so one leap map.
    let needs = voxcube::memory::budget::ViewNeeds {
        ghost: 3,
        maps: 1,
        cell_maps: 0,
        depths: 0,
        node_bytes: 0,
        cell_ranges: 0,
        segments: 0,
    };
    let slab = voxcube::memory::budget::largest_node(&grid, 1, 16, needs, 0)
        .expect("fits")
        .slab;
    let figure = format!(
        "at most {} bytes",
        slab.to_string()
            .as_bytes()
            .rchunks(3)
            .rev()
            .map(|c| std::str::from_utf8(c).unwrap_or(""))
            .collect::<Vec<_>>()
            .join(",")
    );
    assert!(
        text.contains(&figure),
        "docs/porting.md must quote SOD's largest 16-node slab: {figure}"
    );
}
