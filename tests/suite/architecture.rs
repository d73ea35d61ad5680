//! The layout's rules, read from the source of the core crate (`crates/peridyn-core/src`) and
//! the application (`src`, which names the core's modules through its re-exports, as
//! `crate::scene`):
//!
//! - no two files import each other, directly or through others (a file-level circle: two
//!   files whose code uses each other's items), and the top-level modules import each other
//!   in one direction;
//! - no file but those of the builder (the core's `sim/`) names a concrete simulation type —
//!   every type `sim/` implements `solver::Stepper` for; everything else drives the
//!   dimension-erased `Stepper`.
//!
//! `reader` says how a file's imports are read (re-exports followed to the defining file; a
//! `mod.rs` that only declares and re-exports imports nothing).

mod reader;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use reader::{Crate, Tree, words};

/// Circles that are known and left for now, each as its files (relative to the repository),
/// with the reason. An entry that is no longer a circle fails the test, so the list only
/// shrinks.
const ALLOWED_CIRCLES: &[(&[&str], &str)] = &[];

/// The repository's root.
fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The core crate, the application's library and its binary.
fn tree() -> Tree {
    let core = root().join("crates/peridyn-core/src");
    let app = root().join("src");
    Tree::read(vec![
        Crate {
            name: "peridyn_core",
            root: core.join("lib.rs"),
            dir: core,
        },
        Crate {
            name: "peridyn",
            root: app.join("lib.rs"),
            dir: app.clone(),
        },
        Crate {
            name: "",
            root: app.join("main.rs"),
            dir: app,
        },
    ])
}

/// A file as the messages name it.
fn shown(file: &Path) -> String {
    file.strip_prefix(root())
        .unwrap_or(file)
        .display()
        .to_string()
}

/// Node → the nodes it imports.
type Edges = BTreeMap<String, BTreeSet<String>>;

/// The import graph of the files.
fn file_edges(tree: &Tree) -> Edges {
    tree.files
        .keys()
        .map(|f| (shown(f), tree.imports(f).iter().map(|t| shown(t)).collect()))
        .collect()
}

/// The import graph of the top-level modules (both crates' modules by name).
fn module_edges(tree: &Tree) -> Edges {
    let mut edges = Edges::new();
    for file in tree.files.keys() {
        let Some(from) = tree.top_module(file) else {
            continue;
        };
        let entry = edges.entry(from.to_string()).or_default();
        for target in tree.imports(file) {
            if let Some(to) = tree.top_module(&target).filter(|&to| to != from) {
                entry.insert(to.to_string());
            }
        }
    }
    edges
}

/// The circles of a graph: its strongly connected parts of more than one node (Tarjan), each
/// with one closed path through all of its nodes' first member for the message.
fn circles(edges: &Edges) -> Vec<BTreeSet<String>> {
    struct Search<'a> {
        edges: &'a Edges,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        found: Vec<BTreeSet<String>>,
    }
    impl<'a> Search<'a> {
        fn visit(&mut self, at: &'a str) {
            let i = self.index.len();
            self.index.insert(at, i);
            self.low.insert(at, i);
            self.stack.push(at);
            for next in self.edges.get(at).into_iter().flatten() {
                let next = next.as_str();
                if !self.index.contains_key(next) {
                    self.visit(next);
                    let low = self.low[at].min(self.low[next]);
                    self.low.insert(at, low);
                } else if self.stack.contains(&next) {
                    let low = self.low[at].min(self.index[next]);
                    self.low.insert(at, low);
                }
            }
            if self.low[at] == self.index[at] {
                let k = self.stack.iter().position(|&n| n == at).unwrap();
                let part: BTreeSet<String> = self.stack.drain(k..).map(str::to_string).collect();
                if part.len() > 1 {
                    self.found.push(part);
                }
            }
        }
    }
    let mut search = Search {
        edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for node in edges.keys() {
        if !search.index.contains_key(node.as_str()) {
            search.visit(node);
        }
    }
    search.found
}

/// A closed path from `start` back to it (breadth-first: the shortest), for messages.
fn cycle(edges: &Edges, start: &str) -> Vec<String> {
    let mut came_from: BTreeMap<&str, &str> = BTreeMap::new();
    let mut queue = std::collections::VecDeque::from([start]);
    while let Some(at) = queue.pop_front() {
        for next in edges.get(at).into_iter().flatten() {
            if next == start {
                let mut back = Vec::new();
                let mut node = at;
                while node != start {
                    back.push(node.to_string());
                    node = came_from[node];
                }
                back.reverse();
                let mut path = vec![start.to_string()];
                path.extend(back);
                path.push(start.to_string());
                return path;
            }
            if !came_from.contains_key(next.as_str()) && next != start {
                came_from.insert(next, at);
                queue.push_back(next);
            }
        }
    }
    Vec::new()
}

/// The circles of `edges` not allowed by `allowed` (its files, and a closed path through the
/// first), and the allowed ones that are gone.
fn judge(edges: &Edges, allowed: &[(&[&str], &str)]) -> (Vec<String>, Vec<String>) {
    let found = circles(edges);
    let same = |files: &[&str], c: &BTreeSet<String>| {
        files.iter().copied().collect::<BTreeSet<&str>>() == c.iter().map(String::as_str).collect()
    };
    let new = found
        .iter()
        .filter(|c| !allowed.iter().any(|(files, _)| same(files, c)))
        .map(|c| {
            let members: Vec<&str> = c.iter().map(String::as_str).collect();
            let path = cycle(edges, members[0]).join(" → ");
            format!("{} (e.g. {path})", members.join(", "))
        })
        .collect();
    let gone = allowed
        .iter()
        .filter(|(files, _)| !found.iter().any(|c| same(files, c)))
        .map(|(files, _)| files.join(", "))
        .collect();
    (new, gone)
}

#[test]
fn no_two_files_import_each_other() {
    let tree = tree();
    let edges = file_edges(&tree);
    assert!(edges.len() > 100, "read the files: {}", edges.len());
    let sim = "crates/peridyn-core/src/sim/mod.rs";
    assert!(
        edges[sim].contains("crates/peridyn-core/src/solver/mod.rs"),
        "the reader sees imports: {:?}",
        edges[sim]
    );
    let (new, gone) = judge(&edges, ALLOWED_CIRCLES);
    assert!(
        new.is_empty(),
        "file-level import circles:\n{}",
        new.join("\n")
    );
    assert!(
        gone.is_empty(),
        "no longer circles: remove them from ALLOWED_CIRCLES:\n{}",
        gone.join("\n")
    );
}

#[test]
fn the_modules_import_each_other_in_one_direction() {
    let edges = module_edges(&tree());
    assert!(edges.len() > 10, "read the modules: {edges:?}");
    assert!(edges["sim"].contains("solver"), "the reader sees imports");
    assert!(edges["control"].contains("scene"), "and the application's");
    let (new, _) = judge(&edges, &[]);
    assert!(new.is_empty(), "module import circles:\n{}", new.join("\n"));
}

/// The types `code` implements `Stepper` for.
fn steppers(code: &str) -> BTreeSet<String> {
    words(code)
        .windows(3)
        .filter(|w| w[0] == "Stepper" && w[1] == "for")
        .map(|w| w[2].to_string())
        .collect()
}

#[test]
fn only_the_builder_names_a_concrete_simulation() {
    let tree = tree();
    let sim_dir = root().join("crates/peridyn-core/src/sim");
    let in_sim = |file: &PathBuf| file.starts_with(&sim_dir);
    let concrete: BTreeSet<String> = tree
        .files
        .iter()
        .filter(|(file, _)| in_sim(file))
        .flat_map(|(_, f)| steppers(&f.code))
        .collect();
    assert!(!concrete.is_empty(), "no `impl Stepper for` found in sim/");
    let mut found = Vec::new();
    for (file, f) in tree.files.iter().filter(|(file, _)| !in_sim(file)) {
        let named: BTreeSet<&str> = words(&f.code)
            .into_iter()
            .filter(|w| concrete.contains(*w))
            .collect();
        for name in named {
            found.push(format!("{}: {name}", shown(file)));
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

#[test]
fn the_concrete_types_are_read_from_the_stepper_impls() {
    let code = "impl<const D: usize> Stepper for A<D> {}\nimpl solver::Stepper for B {}\n\
                impl Other for C {}\nfn f(s: &dyn Stepper) {}";
    assert_eq!(steppers(code), BTreeSet::from(["A".into(), "B".into()]));
}

#[test]
fn circles_are_found_named_and_allowed_only_while_they_exist() {
    let edges: Edges = [("a", "b"), ("b", "c"), ("c", "a"), ("c", "d"), ("d", "e")]
        .iter()
        .fold(Edges::new(), |mut e, (from, to)| {
            e.entry(from.to_string())
                .or_default()
                .insert(to.to_string());
            e
        });
    let found = circles(&edges);
    assert_eq!(found.len(), 1);
    assert_eq!(
        found[0],
        BTreeSet::from(["a".into(), "b".into(), "c".into()])
    );
    assert_eq!(cycle(&edges, "b"), ["b", "c", "a", "b"]);
    let (new, gone) = judge(&edges, &[]);
    assert_eq!(new, ["a, b, c (e.g. a → b → c → a)"]);
    assert!(gone.is_empty());
    let allowed: &[(&[&str], &str)] = &[(&["c", "b", "a"], "known"), (&["d", "e"], "fixed")];
    let (new, gone) = judge(&edges, allowed);
    assert!(new.is_empty());
    assert_eq!(gone, ["d, e"]);
}

/// A source file's length limit (one job per file), counted with its tests where they share
/// the file.
const MAX_FILE_LINES: usize = 900;
/// A function's length limit outside tests.
const MAX_FUNCTION_LINES: usize = 150;

/// The functions of some code (comments and literals stripped, line breaks kept) longer than
/// `limit` lines: (name, first line, lines).
fn long_functions(code: &str, limit: usize) -> Vec<(String, usize, usize)> {
    let bytes = code.as_bytes();
    let mut found = Vec::new();
    for (k, _) in code.match_indices("fn ") {
        let before = code[..k].chars().last();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let name: String = code[k + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        // The body: from the first `{` before any `;` (a declaration without a body has none).
        let Some(open) = code[k..].find(['{', ';']).map(|o| k + o) else {
            continue;
        };
        if bytes[open] == b';' {
            continue;
        }
        let mut depth = 0;
        let mut close = code.len();
        for (i, &b) in bytes.iter().enumerate().skip(open) {
            match b {
                b'{' => depth += 1,
                b'}' => {
                    depth -= 1;
                    if depth == 0 {
                        close = i;
                        break;
                    }
                }
                _ => {}
            }
        }
        let first = code[..k].matches('\n').count() + 1;
        let lines = code[k..close].matches('\n').count() + 1;
        if lines > limit {
            found.push((name, first, lines));
        }
    }
    found
}

#[test]
fn no_file_is_over_900_lines_and_no_function_over_150() {
    let mut too_long = Vec::new();
    for dir in [root().join("crates/peridyn-core/src"), root().join("src")] {
        let mut files = Vec::new();
        rust_files(&dir, &mut files);
        for file in files {
            let text = std::fs::read_to_string(&file).unwrap();
            let lines = text.lines().count();
            if lines > MAX_FILE_LINES {
                too_long.push(format!("{}: {lines} lines", shown(&file)));
            }
            // A file of tests (`mod tests;` beside the code) holds no function the rule counts.
            if file.file_name().is_some_and(|n| n == "tests.rs") {
                continue;
            }
            for (name, line, count) in long_functions(&reader::code(&text), MAX_FUNCTION_LINES) {
                too_long.push(format!("{}:{line}: fn {name}, {count} lines", shown(&file)));
            }
        }
    }
    assert!(too_long.is_empty(), "too long:\n{}", too_long.join("\n"));
}

#[test]
fn long_functions_are_measured_from_their_name_to_their_closing_brace() {
    let code = "fn short() {\n}\nfn long() {\n    if x {\n    }\n\n}\nfn decl();\n";
    assert_eq!(long_functions(code, 3), [("long".to_string(), 3, 5)]);
    assert!(long_functions(code, 5).is_empty());
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}
