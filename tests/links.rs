//! Relative links and anchors in the README, `docs/` and the CHANGELOG lead somewhere: each
//! linked file exists, and each `#anchor` is a heading of the file it points into (as GitHub
//! makes anchors from headings). No network: links with a scheme are not followed.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// The anchor GitHub gives a heading: lower case, letters, digits, `-` and `_` kept, spaces
/// made `-`, everything else dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            '-' | '_' => Some(c),
            c if c.is_alphanumeric() => Some(c),
            _ => None,
        })
        .collect()
}

/// The lines of `text` outside fenced code blocks, with their line numbers (from 1).
fn prose(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            out.push((i + 1, line));
        }
    }
    out
}

/// `line` without its inline code spans.
fn without_code(line: &str) -> String {
    let mut out = String::new();
    for (k, part) in line.split('`').enumerate() {
        if k % 2 == 0 {
            out.push_str(part);
        }
    }
    out
}

/// The anchors of a Markdown text's headings (a repeated heading gets `-1`, `-2`, …).
fn anchors(text: &str) -> HashSet<String> {
    let mut out = HashSet::new();
    for (_, line) in prose(text) {
        let Some(heading) = line.strip_prefix('#') else {
            continue;
        };
        let heading = heading.trim_start_matches('#');
        if !heading.starts_with(' ') {
            continue;
        }
        // Code keeps its text; a link in a heading shows its text.
        let text = heading.replace(['`', '[', ']'], "");
        let text = match text.find("](") {
            Some(_) => text.split('(').next().unwrap_or_default().to_owned(),
            None => text,
        };
        let base = slug(&text);
        let mut anchor = base.clone();
        let mut n = 0;
        while !out.insert(anchor.clone()) {
            n += 1;
            anchor = format!("{base}-{n}");
        }
    }
    out
}

/// The link targets of a Markdown text, with their line numbers: inline links and images
/// (`[text](target)`) and reference definitions (`[name]: target`).
fn targets(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    for (number, line) in prose(text) {
        let line = without_code(line);
        let mut rest = line.as_str();
        while let Some(at) = rest.find("](") {
            rest = &rest[at + 2..];
            let end = rest.find(')').unwrap_or(rest.len());
            let target = rest[..end].split_whitespace().next().unwrap_or_default();
            out.push((number, target.trim_matches(['<', '>']).to_owned()));
            rest = &rest[end..];
        }
        let trimmed = line.trim_start();
        if let Some(close) = trimmed.strip_prefix('[').and_then(|t| t.find("]:")) {
            let target = trimmed[close + 3..].split_whitespace().next();
            out.extend(target.map(|t| (number, t.to_owned())));
        }
    }
    out
}

/// The broken links of the Markdown file `file` whose text is `text`, each as
/// `file:line: target: why`.
fn broken(file: &Path, text: &str) -> Vec<String> {
    let dir = file.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (line, target) in targets(text) {
        if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (path, anchor) = target.split_once('#').unwrap_or((&target, ""));
        let resolved = if path.is_empty() {
            file.to_path_buf()
        } else {
            dir.join(path)
        };
        let why = if !resolved.exists() {
            Some("no such file".to_owned())
        } else if anchor.is_empty() {
            None
        } else if resolved.extension().is_none_or(|e| e != "md") {
            // An anchor into a source file (`#L10`) or a folder is not checked.
            None
        } else {
            let linked = match path {
                "" => text.to_owned(),
                _ => std::fs::read_to_string(&resolved).unwrap_or_default(),
            };
            (!anchors(&linked).contains(anchor)).then(|| format!("no heading #{anchor}"))
        };
        if let Some(why) = why {
            out.push(format!("{}:{line}: {target}: {why}", file.display()));
        }
    }
    out
}

/// The Markdown files the check covers: the README, the CHANGELOG and everything in `docs/`.
fn documents() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = vec![root.join("README.md"), root.join("CHANGELOG.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

#[test]
fn relative_links_and_anchors_lead_somewhere() {
    let mut all = Vec::new();
    for file in documents() {
        let text = std::fs::read_to_string(&file).expect("readable");
        all.extend(broken(&file, &text));
    }
    assert!(all.is_empty(), "broken links:\n{}", all.join("\n"));
}

#[test]
fn the_check_finds_a_planted_broken_link() {
    let readme = Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md");
    let text = "# Title\n\n## Second part (α, 2×)\n\n\
                [fine](#second-part-α-2) [fine too](docs/performance.md)\n\
                [gone](docs/no-such-page.md) [no anchor](#third-part) `[code](nowhere.md)`\n\
                ```\n[fenced](nowhere.md)\n```\n[ref]: docs/missing.md\n";
    let found = broken(&readme, text);
    assert_eq!(found.len(), 3, "{found:#?}");
    assert!(found[0].ends_with("docs/no-such-page.md: no such file"));
    assert!(found[1].ends_with("#third-part: no heading #third-part"));
    assert!(found[2].contains(":10: docs/missing.md"));
}

#[test]
fn anchors_are_made_as_github_makes_them() {
    let text = "# Aerobic class (Figure 11)\n## `PolygonBudget` and α\n## Notes\n## Notes\n";
    let a = anchors(text);
    for expected in [
        "aerobic-class-figure-11",
        "polygonbudget-and-α",
        "notes",
        "notes-1",
    ] {
        assert!(a.contains(expected), "{expected} in {a:?}");
    }
}
