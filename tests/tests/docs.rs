//! The documentation holds together: every relative link of README.md and docs/ names a file
//! that exists, and the README stays a front door (at most 12 KiB).

use std::path::{Path, PathBuf};

/// The relative link targets of markdown `text` (no URLs, no bare anchors), anchors cut off.
fn links(text: &str) -> Vec<&str> {
    text.split("](")
        .skip(1)
        .filter_map(|rest| rest.split(')').next())
        .map(|target| target.split('#').next().unwrap_or(""))
        .filter(|t| !t.is_empty() && !t.contains("://") && !t.starts_with("mailto:"))
        .collect()
}

/// The links of the markdown file `page` whose targets do not exist.
fn broken(page: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(page).expect("a documentation page");
    let dir = page.parent().expect("a folder");
    links(&text)
        .into_iter()
        .filter(|t| !dir.join(t).exists())
        .map(|t| format!("{}: {t}", page.display()))
        .collect()
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn every_relative_link_of_the_docs_names_a_file() {
    let mut pages = vec![root().join("README.md")];
    for entry in std::fs::read_dir(root().join("docs")).expect("docs/") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "md") {
            pages.push(path);
        }
    }
    assert!(pages.len() > 5, "the docs pages: {pages:?}");
    let broken: Vec<String> = pages.iter().flat_map(|p| broken(p)).collect();
    assert!(broken.is_empty(), "broken links: {broken:#?}");
}

#[test]
fn the_link_check_sees_links_and_skips_urls_and_anchors() {
    let text = "[a](docs/a.md) [b](b.md#part) [c](https://example.org) [d](#here)";
    assert_eq!(links(text), ["docs/a.md", "b.md"]);
}

#[test]
fn the_readme_is_a_front_door() {
    let bytes = std::fs::metadata(root().join("README.md"))
        .expect("README.md")
        .len();
    assert!(
        bytes <= 12 * 1024,
        "README.md is {bytes} bytes; at most 12 KiB"
    );
}
