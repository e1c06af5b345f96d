//! The README and the book (`docs/src`) link only to what exists: every relative link names a
//! file of the repository, and every `#anchor` a heading of its target, with mdBook's anchors
//! (lowercase, spaces to `-`, other punctuation dropped). Links to the web are not followed.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The repository's root.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().expect("the repository")
}

/// The Markdown files a reader meets: the README and every page of the book.
fn pages() -> Vec<PathBuf> {
    let mut pages = vec![root().join("README.md")];
    let book = root().join("docs/src");
    let mut chapters: Vec<PathBuf> = std::fs::read_dir(&book)
        .unwrap_or_else(|e| panic!("{}: {e}", book.display()))
        .map(|entry| entry.expect("a directory entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "md"))
        .collect();
    chapters.sort();
    pages.extend(chapters);
    pages
}

/// The text outside fenced code blocks, where links are links.
fn prose(text: &str) -> String {
    let mut fenced = false;
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out += line;
            out.push('\n');
        }
    }
    out
}

/// The targets of the Markdown links `[text](target)` in `text`, inline code left out.
fn links(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for line in prose(text).lines() {
        // Spans of inline code hold no links.
        let plain: String = line.split('`').step_by(2).collect::<Vec<_>>().join(" ");
        let mut rest = plain.as_str();
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let end = rest.find(')').unwrap_or(rest.len());
            let target = rest[..end].split_whitespace().next().unwrap_or("");
            found.push(target.to_owned());
            rest = &rest[end..];
        }
    }
    found
}

/// mdBook's anchor of a heading: lowercase, spaces to `-`, letters, digits, `-` and `_` kept.
fn anchor(heading: &str) -> String {
    let text = heading.trim_start_matches('#').trim().replace('`', "");
    text.chars()
        .filter_map(|c| match c {
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c.to_ascii_lowercase()),
            c if c.is_whitespace() => Some('-'),
            _ => None,
        })
        .collect()
}

/// The anchors of every heading of the Markdown file at `path`.
fn anchors(path: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    prose(&text).lines().filter(|l| l.starts_with('#')).map(anchor).collect()
}

#[test]
fn every_link_of_the_readme_and_the_book_resolves() {
    let mut checked = 0;
    let mut broken = Vec::new();
    let pages = pages();
    assert!(pages.len() > 5, "the book has its chapters: {pages:?}");
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap_or_else(|e| panic!("{}: {e}", page.display()));
        for target in links(&text) {
            if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            checked += 1;
            let (file, fragment) = target.split_once('#').unwrap_or((&target, ""));
            let resolved = if file.is_empty() { page.clone() } else { page.parent().expect("a folder").join(file) };
            if !resolved.exists() {
                broken.push(format!("{}: {target}: no such file", page.display()));
            } else if !fragment.is_empty() && !anchors(&resolved).contains(fragment) {
                broken.push(format!("{}: {target}: no such heading in {}", page.display(), resolved.display()));
            }
        }
    }
    assert!(broken.is_empty(), "{} of {checked} links broken:\n{}", broken.len(), broken.join("\n"));
    assert!(checked > 20, "links were read: {checked}");
}

#[test]
fn anchors_are_mdbooks() {
    assert_eq!(anchor("## The sensor spec (TOML)"), "the-sensor-spec-toml");
    assert_eq!(anchor("### `run --model`: answers"), "run---model-answers");
    assert_eq!(links("see [Samples](formats.md#samples) and `[not](a link)`"), ["formats.md#samples"]);
}
