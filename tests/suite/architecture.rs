//! The layout's rules, read from the source: the modules of `src/` import each other in one
//! direction only (no circle), and no module but the builder (`src/sim/`) names a concrete
//! simulation type — everything else drives the dimension-erased `solver::Stepper`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The concrete simulation types, named only inside `src/sim/`.
const CONCRETE: &[&str] = &["DynamicSimulation", "ScalarSimulation"];

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a file without comments and without its test module (by convention the last
/// item, after `#[cfg(test)]`).
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or_default();
    text.lines()
        .map(|line| match line.find("//") {
            Some(k) => &line[..k],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The top-level module a file belongs to (`src/scene/units.rs` → `scene`); None for the crate
/// roots.
fn module_of(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()?
        .as_os_str()
        .to_string_lossy()
        .to_string();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib" && name != "main").then_some(name)
}

/// Top-level modules named after `crate::` (also inside `crate::{a, b::c}` groups), and after
/// `super::` in a top-level module's own file.
fn imports(code: &str, top_file: bool) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let mut prefixes = vec!["crate::"];
    if top_file {
        prefixes.push("super::");
    }
    for prefix in prefixes {
        for (k, _) in code.match_indices(prefix) {
            let rest = &code[k + prefix.len()..];
            if let Some(group) = rest.strip_prefix('{') {
                let mut depth = 0;
                let mut item_start = true;
                for (i, c) in group.char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => item_start = true,
                        c if c.is_whitespace() => {}
                        _ if item_start && depth == 0 => {
                            found.insert(ident(&group[i..]));
                            item_start = false;
                        }
                        _ => {}
                    }
                }
            } else {
                found.insert(ident(rest));
            }
        }
    }
    found.retain(|m| !m.is_empty() && m != "self");
    found
}

/// Module → the modules it imports.
type Edges = BTreeMap<String, BTreeSet<String>>;

/// The import graph of the top-level modules, and every file's code.
fn graph() -> (Edges, Vec<(PathBuf, String)>) {
    let mut edges = Edges::new();
    let mut texts = Vec::new();
    for src in roots() {
        let mut files = Vec::new();
        sources(&src, &mut files);
        for file in files {
            let text = code(&std::fs::read_to_string(&file).unwrap());
            if let Some(module) = module_of(&src, &file) {
                let rel = file.strip_prefix(&src).unwrap();
                let top_file = rel.components().count() == 1 || rel.ends_with("mod.rs");
                let entry = edges.entry(module.clone()).or_default();
                for m in imports(&text, top_file) {
                    if m != module {
                        entry.insert(m);
                    }
                }
            }
            texts.push((file, text));
        }
    }
    (edges, texts)
}

/// The source roots: the core crate's and the application's (whose modules name the core's
/// through its re-exports, as `crate::scene`).
fn roots() -> [PathBuf; 2] {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    [root.join("crates/peridyn-core/src"), root.join("src")]
}

/// A circle through `start`, if there is one (depth-first search).
fn circle(edges: &Edges, start: &str) -> Option<Vec<String>> {
    fn visit(
        edges: &Edges,
        start: &str,
        at: &str,
        path: &mut Vec<String>,
        seen: &mut BTreeSet<String>,
    ) -> bool {
        for next in edges.get(at).into_iter().flatten() {
            if next == start {
                path.push(next.clone());
                return true;
            }
            if seen.insert(next.clone()) {
                path.push(next.clone());
                if visit(edges, start, next, path, seen) {
                    return true;
                }
                path.pop();
            }
        }
        false
    }
    let mut path = vec![start.to_string()];
    visit(edges, start, start, &mut path, &mut BTreeSet::new()).then_some(path)
}

#[test]
fn the_modules_import_each_other_in_one_direction() {
    let (edges, _) = graph();
    assert!(edges.len() > 10, "read the modules: {edges:?}");
    assert!(edges["sim"].contains("solver"), "the reader sees imports");
    let circles: Vec<String> = edges
        .keys()
        .filter_map(|m| circle(&edges, m))
        .map(|c| c.join(" → "))
        .collect();
    assert!(
        circles.is_empty(),
        "import circles:\n{}",
        circles.join("\n")
    );
}

#[test]
fn only_the_builder_names_a_concrete_simulation() {
    let (_, texts) = graph();
    let sim_dir = roots()[0].join("sim");
    let mut found = Vec::new();
    for (file, text) in &texts {
        if file.starts_with(&sim_dir) {
            continue;
        }
        for name in CONCRETE {
            if text.contains(name) {
                found.push(format!("{}: {name}", file.display()));
            }
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn the_reader_finds_grouped_and_nested_imports() {
    let code = "use crate::{a::{b, c}, d, self};\nfn f() { crate::e::g(); }\nuse super::h;";
    let found: Vec<String> = imports(code, true).into_iter().collect();
    assert_eq!(found, ["a", "d", "e", "h"]);
    assert!(imports("use super::h;", false).is_empty());
    let mut edges = BTreeMap::new();
    edges.insert("x".to_string(), BTreeSet::from(["y".to_string()]));
    edges.insert("y".to_string(), BTreeSet::from(["x".to_string()]));
    assert_eq!(circle(&edges, "x").unwrap(), ["x", "y", "x"]);
}
