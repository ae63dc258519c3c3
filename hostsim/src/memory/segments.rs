//! A pre-integrated view's table (`voxcube_kernel::optics::segments`): it depends on the
//! view's transfer function and Δt alone, so a host builds it once per view and lends it to
//! every node that traces the view; the budget counts a copy on each node, as a machine
//! without shared memory holds it.
//!
//! Invariant: a pre-integrated view's every slab carries its table, or the view is not
//! rendered: the kernel composites such a view by nothing else.

use voxcube_kernel::optics::segments::{self, Layout, Segments};
use voxcube_kernel::trace::view::{Mode, View};
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;
use voxcube_kernel::Vec4;

/// A view's pre-integration table, or none for a view that does not composite so.
#[derive(Debug, Default)]
pub struct SegmentTable {
    table: Option<(Layout, Vec<Vec4>)>,
}

impl SegmentTable {
    /// `view`'s table: empty unless it composites pre-integrated.
    pub fn of(view: &View) -> SegmentTable {
        let (Some(layout), Mode::Composite(tf)) = (view.segments(), &view.spec().mode) else {
            return SegmentTable::default();
        };
        let mut cells = vec![Vec4::ZERO; segments::LEN];
        match segments::build(tf, layout, &mut cells) {
            Ok(()) => SegmentTable {
                table: Some((*layout, cells)),
            },
            // Never: the cells are a table's length. A slab without its table renders nothing.
            Err(_) => SegmentTable::default(),
        }
    }

    /// Bytes it holds.
    pub fn bytes(&self) -> usize {
        self.table
            .as_ref()
            .map_or(0, |(_, cells)| cells.len() * size_of::<Vec4>())
    }

    /// `slab`, compositing by this table (unchanged when it holds none).
    pub fn apply<'a, T: Sample>(&'a self, slab: Slab<'a, T>) -> Slab<'a, T> {
        match &self.table {
            Some((layout, cells)) => match Segments::new(*layout, cells) {
                Ok(table) => slab.with_segments(table),
                Err(_) => slab,
            },
            None => slab,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::Scene;

    fn view_of(compositing: &str, accuracy: &str) -> View {
        let text = format!(
            "[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nmode = \"composite\"\naccuracy = \"{accuracy}\"\ncompositing = \"{compositing}\"\n[[datasets.views.transfer]]\nvalue = 10.0\ncolor = [0.2, 0.3, 0.8]\nopacity = 0.0\n[[datasets.views.transfer]]\nvalue = 200.0\ncolor = [1.0, 0.2, 0.1]\nopacity = 0.8\n"
        );
        let jobs = Scene::parse(&text, "t.toml", std::path::Path::new("."))
            .and_then(Scene::load)
            .unwrap_or_else(|e| panic!("{e}"));
        jobs.into_iter()
            .next()
            .and_then(|d| d.views.into_iter().next())
            .map(|v| v.view)
            .unwrap_or_else(|| panic!("a view"))
    }

    #[test]
    fn only_a_pre_integrated_view_has_a_table_and_the_budget_counts_what_it_holds() {
        let pre = view_of("pre-integrated", "fast");
        let table = SegmentTable::of(&pre);
        assert_eq!(table.bytes(), segments::BYTES);
        let needs = crate::memory::budget::ViewNeeds::of(&pre);
        assert_eq!(needs.segments, table.bytes());
        for view in [view_of("sampled", "fast"), view_of("sampled", "exact")] {
            assert_eq!(SegmentTable::of(&view).bytes(), 0);
            assert_eq!(crate::memory::budget::ViewNeeds::of(&view).segments, 0);
        }
    }

    #[test]
    fn pre_integration_outside_the_fast_tier_is_refused_naming_the_key() {
        let text = "[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nmode = \"composite\"\ncompositing = \"pre-integrated\"\n[[datasets.views.transfer]]\nvalue = 10.0\ncolor = [0.2, 0.3, 0.8]\nopacity = 0.5\n";
        let err = Scene::parse(text, "t.toml", std::path::Path::new("."))
            .and_then(Scene::load)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(err.contains("compositing") && err.contains("fast"), "{err}");
        let unknown = text.replace("\"pre-integrated\"", "\"preintegrated\"");
        let err = Scene::parse(&unknown, "t.toml", std::path::Path::new("."))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(err.contains("unknown compositing `preintegrated`"), "{err}");
    }
}
