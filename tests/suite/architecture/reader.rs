//! The import reader of the architecture test: which file's code uses which file's items.
//!
//! Comments, the contents of string and character literals and `#[cfg(test)]` items are
//! dropped first. A file imports the file that defines what a path names: a `use` declaration
//! (groups expanded; `self` in a group names the module) or a path in code that starts at
//! `crate::`, `super::`, `self::`, a crate's name (`peridyn_core::`, `peridyn::`), a module the
//! file declares (`mod x;`, itself no import) or a name a `use` brought in. `crate::a::b::C`
//! is `a/b.rs` or `a/b/mod.rs`, or, where `b` is an item, the file of `a`.
//!
//! Re-exports are followed to the defining file: a `pub use child::X` names `X` for others but
//! is no import of the file that writes it, unless that file's own code uses `X`. So a `mod.rs`
//! that only declares and re-exports imports nothing, and `use super::X` in a sibling imports
//! the file that defines `X`: a circle through a `mod.rs` is one only where its own code uses
//! what imports it. A glob `use m::*` imports `m`'s own file (`pub use m::*` only re-exports).
//! A `use` of a module itself (`use super::schema;`) imports nothing until code names an item
//! through it. A file's own items used by name are not told apart from a re-export's only by
//! paths: a re-exported name counts as used where it stands alone (not `a::name`, `.name`).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A crate: its name in other crates' paths, the directory of its modules and its root file.
pub struct Crate {
    pub name: &'static str,
    pub dir: PathBuf,
    pub root: PathBuf,
}

/// An absolute path: a crate (its index) and the segments below its root.
type Abs = (usize, Vec<String>);

/// One name a `use` declaration brings in.
#[derive(Debug, Clone, PartialEq)]
pub struct UseItem {
    pub path: Vec<String>,
    /// The name it is known by; None for a glob.
    pub name: Option<String>,
    /// `pub`, `pub(crate)`, `pub(super)`: a re-export.
    pub public: bool,
}

/// A source file as the reader sees it.
pub struct File {
    krate: usize,
    module: Vec<String>,
    /// The code without comments, literals and tests.
    pub code: String,
    /// `code` without its `use` declarations.
    body: String,
    uses: Vec<UseItem>,
    /// The modules it declares (`mod x;`).
    children: BTreeSet<String>,
    /// The names its `use` declarations bring in, as absolute paths.
    aliases: BTreeMap<String, Abs>,
}

/// Every file of some crates, and which module each is.
pub struct Tree {
    crates: Vec<Crate>,
    pub files: BTreeMap<PathBuf, File>,
    modules: BTreeMap<Abs, PathBuf>,
}

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The words (identifiers and keywords) of some code, in order.
pub fn words(code: &str) -> Vec<&str> {
    code.split(|c: char| !is_ident(c))
        .filter(|w| !w.is_empty())
        .collect()
}

/// The code of a file: comments, literals' contents and `#[cfg(test)]` items removed.
pub fn code(text: &str) -> String {
    let mut out = strip_literals(text);
    while let Some(k) = out.find("#[cfg(test)]") {
        let end = item_end(&out, k + "#[cfg(test)]".len());
        out.replace_range(k..end, "");
    }
    out
}

/// `text` without comments and with empty string and character literals; line breaks kept.
fn strip_literals(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    // Skips to `end`, keeping the line breaks on the way.
    let skip = |out: &mut String, from: usize, end: usize| {
        out.extend(c[from..end.min(c.len())].iter().filter(|&&ch| ch == '\n'));
        end
    };
    while i < c.len() {
        let after_ident = i > 0 && is_ident(c[i - 1]);
        if c[i] == '/' && c.get(i + 1) == Some(&'/') {
            let end = c[i..]
                .iter()
                .position(|&ch| ch == '\n')
                .map_or(c.len(), |k| i + k);
            i = skip(&mut out, i, end);
        } else if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            let (mut depth, mut j) = (0, i);
            while j < c.len() {
                if c[j] == '/' && c.get(j + 1) == Some(&'*') {
                    depth += 1;
                    j += 1;
                } else if c[j] == '*' && c.get(j + 1) == Some(&'/') {
                    depth -= 1;
                    j += 1;
                    if depth == 0 {
                        j += 1;
                        break;
                    }
                }
                j += 1;
            }
            i = skip(&mut out, i, j);
        } else if let Some((open, hashes)) = (!after_ident).then(|| raw_string(&c, i)).flatten() {
            let close: Vec<char> = std::iter::once('"')
                .chain(std::iter::repeat_n('#', hashes))
                .collect();
            let end = (open..c.len())
                .find(|&j| c[j..].starts_with(&close))
                .map_or(c.len(), |j| j + close.len());
            out.push_str("\"\"");
            i = skip(&mut out, open, end);
        } else if c[i] == '"' {
            let mut j = i + 1;
            while j < c.len() && c[j] != '"' {
                j += if c[j] == '\\' { 2 } else { 1 };
            }
            out.push_str("\"\"");
            i = skip(&mut out, i + 1, j + 1);
        } else if c[i] == '\'' && c.get(i + 1) == Some(&'\\') {
            let end = (i + 3..c.len())
                .find(|&j| c[j] == '\'')
                .map_or(c.len(), |j| j + 1);
            out.push_str("' '");
            i = end;
        } else if c[i] == '\'' && c.get(i + 2) == Some(&'\'') {
            out.push_str("' '");
            i += 3;
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// A raw string starting at `i` (`r"`, `r#"`, `br"`, …): where its contents start and how many
/// `#` close it.
fn raw_string(c: &[char], i: usize) -> Option<(usize, usize)> {
    let mut j = i + usize::from(c[i] == 'b');
    if c.get(j) != Some(&'r') {
        return None;
    }
    j += 1;
    let hashes = c[j..].iter().take_while(|&&ch| ch == '#').count();
    (c.get(j + hashes) == Some(&'"')).then_some((j + hashes + 1, hashes))
}

/// The end of the item that starts at `from` (after its attributes): its `;` or closing brace
/// (or the `,` of a field), not past the brace that closes what holds it.
fn item_end(code: &str, from: usize) -> usize {
    let (mut braces, mut nest) = (0i32, 0i32);
    for (i, b) in code.bytes().enumerate().skip(from) {
        match b {
            b'{' => braces += 1,
            b'}' if braces == 0 => return i,
            b'}' => {
                braces -= 1;
                if braces == 0 {
                    return i + 1;
                }
            }
            b'(' | b'[' => nest += 1,
            b')' | b']' => nest -= 1,
            b';' | b',' if braces == 0 && nest == 0 => return i + 1,
            _ => {}
        }
    }
    code.len()
}

/// The `use` declarations of some code, expanded, and the code with them blanked out.
pub fn uses(code: &str) -> (Vec<UseItem>, String) {
    let mut items = Vec::new();
    let mut body = code.to_string();
    let mut from = 0;
    while let Some(k) = code[from..].find("use").map(|k| k + from) {
        from = k + 3;
        let before = code[..k].trim_end();
        let word_start = !code[..k].ends_with(is_ident) && !code[k + 3..].starts_with(is_ident);
        let (public, start) = visibility(before);
        let opens = public || before.is_empty() || before.ends_with([';', '{', '}', ']']);
        if !(word_start && opens) {
            continue;
        }
        let Some(end) = code[k..].find(';').map(|e| k + e) else {
            break;
        };
        let tokens = use_tokens(&code[k + 3..end]);
        let mut pos = 0;
        let mut found = Vec::new();
        use_tree(&tokens, &mut pos, Vec::new(), &mut found);
        items.extend(
            found
                .into_iter()
                .map(|(path, name)| UseItem { path, name, public }),
        );
        let start = if public { start } else { k };
        body.replace_range(start..=end, &" ".repeat(end + 1 - start));
        from = end;
    }
    (items, body)
}

/// Whether code ending in `before` ends with a visibility (`pub`, `pub(crate)`, …), and where
/// it starts.
fn visibility(before: &str) -> (bool, usize) {
    let pub_at = |s: &str| {
        let s = s.trim_end();
        (s.ends_with("pub") && !s[..s.len() - 3].ends_with(is_ident)).then(|| s.len() - 3)
    };
    if let Some(k) = pub_at(before) {
        return (true, k);
    }
    if before.ends_with(')')
        && let Some(open) = before.rfind('(')
        && let Some(k) = pub_at(&before[..open])
    {
        return (true, k);
    }
    (false, before.len())
}

/// The tokens of a use tree: names, `::`, `{`, `}`, `,`, `*`.
fn use_tokens(tree: &str) -> Vec<String> {
    let mut tokens = Vec::new();
    let mut rest = tree.trim();
    while !rest.is_empty() {
        let len = if rest.starts_with("::") {
            2
        } else if rest.starts_with(is_ident) {
            rest.find(|c: char| !is_ident(c)).unwrap_or(rest.len())
        } else {
            rest.chars().next().map_or(1, char::len_utf8)
        };
        let token = &rest[..len];
        if !token.trim().is_empty() {
            tokens.push(token.to_string());
        }
        rest = &rest[len..];
    }
    tokens
}

/// Expands the use tree at `pos` below `prefix` into (path, name) pairs (name None: a glob).
fn use_tree(
    tokens: &[String],
    pos: &mut usize,
    mut prefix: Vec<String>,
    out: &mut Vec<(Vec<String>, Option<String>)>,
) {
    while let Some(token) = tokens.get(*pos) {
        *pos += 1;
        match token.as_str() {
            "::" => {}
            "*" => return out.push((prefix, None)),
            "{" => {
                while tokens.get(*pos).is_some_and(|t| t != "}") {
                    use_tree(tokens, pos, prefix.clone(), out);
                    if tokens.get(*pos).is_some_and(|t| t == ",") {
                        *pos += 1;
                    }
                }
                *pos += 1;
                return;
            }
            segment if tokens.get(*pos).is_some_and(|t| t == "::") => {
                prefix.push(segment.to_string());
            }
            segment => {
                let alias = (tokens.get(*pos).is_some_and(|t| t == "as"))
                    .then(|| tokens.get(*pos + 1).cloned())
                    .flatten();
                if alias.is_some() {
                    *pos += 2;
                }
                if segment != "self" {
                    prefix.push(segment.to_string());
                }
                let name = alias.or_else(|| prefix.last().cloned());
                return out.push((prefix, name));
            }
        }
    }
}

/// The paths in some code: `a::b::c` sequences (cut at `::<` and `::{`), each from its start.
pub fn paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("::").map(|k| k + from) {
        from = k + 2;
        let start = code[..k].trim_end_matches(is_ident).len();
        if start == k || code[..start].ends_with("::") {
            continue;
        }
        let mut segments = vec![code[start..k].to_string()];
        let mut at = k;
        while code[at..].starts_with("::") {
            let name: String = code[at + 2..]
                .chars()
                .take_while(|&c| is_ident(c))
                .collect();
            if name.is_empty() {
                break;
            }
            at += 2 + name.len();
            segments.push(name);
        }
        from = at.max(from);
        out.push(segments);
    }
    out
}

/// Whether `code` names `name` itself: not as a segment inside a path (`a::name`) nor as a
/// field or method (`.name`).
fn names(code: &str, name: &str) -> bool {
    code.match_indices(name).any(|(k, _)| {
        let before = code[..k].trim_end();
        let word = !code[..k].ends_with(is_ident) && !code[k + name.len()..].starts_with(is_ident);
        word && !before.ends_with("::") && !before.ends_with('.')
    })
}

/// Whether `code` defines an item called `name`.
fn defines(code: &str, name: &str) -> bool {
    const KINDS: [&str; 10] = [
        "struct",
        "enum",
        "fn",
        "trait",
        "type",
        "const",
        "static",
        "union",
        "mod",
        "macro_rules",
    ];
    words(code)
        .windows(2)
        .any(|w| w[1] == name && KINDS.contains(&w[0]))
}

impl Tree {
    /// The files of `crates`, read from their directories.
    pub fn read(crates: Vec<Crate>) -> Tree {
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
        let mut texts = Vec::new();
        for krate in &crates {
            let mut files = Vec::new();
            sources(&krate.dir, &mut files);
            for file in files {
                let text = std::fs::read_to_string(&file).unwrap();
                texts.push((file, text));
            }
        }
        Tree::new(crates, texts)
    }

    /// The tree of some files' texts (a file belongs to the crate it is the root of, else to
    /// the crate whose directory holds it).
    pub fn new(crates: Vec<Crate>, texts: Vec<(PathBuf, String)>) -> Tree {
        let mut files = BTreeMap::new();
        let mut modules = BTreeMap::new();
        for (path, text) in texts {
            let Some(krate) = crates.iter().position(|c| c.root == path).or_else(|| {
                let roots: Vec<&PathBuf> = crates.iter().map(|c| &c.root).collect();
                crates.iter().position(|c| {
                    path.starts_with(&c.dir)
                        && !roots.contains(&&path)
                        && c.root.file_name().is_some_and(|n| n == "lib.rs")
                })
            }) else {
                continue;
            };
            let module: Vec<String> = if crates[krate].root == path {
                Vec::new()
            } else {
                let rel = path.strip_prefix(&crates[krate].dir).unwrap();
                let mut m: Vec<String> = rel
                    .iter()
                    .map(|s| s.to_string_lossy().trim_end_matches(".rs").to_string())
                    .collect();
                if m.last().is_some_and(|l| l == "mod") {
                    m.pop();
                }
                m
            };
            if files.contains_key(&path) {
                continue;
            }
            let code = code(&text);
            let (uses, body) = uses(&code);
            let children = words(&body)
                .windows(2)
                .filter(|w| w[0] == "mod")
                .map(|w| w[1].to_string())
                .collect();
            modules.insert((krate, module.clone()), path.clone());
            let file = File {
                krate,
                module,
                code,
                body,
                uses,
                children,
                aliases: BTreeMap::new(),
            };
            files.insert(path, file);
        }
        let mut tree = Tree {
            crates,
            files,
            modules,
        };
        let paths: Vec<PathBuf> = tree.files.keys().cloned().collect();
        for path in paths {
            let mut aliases = BTreeMap::new();
            // A `use` may start at a name another `use` brought in.
            for _ in 0..3 {
                for u in &tree.files[&path].uses {
                    if let (Some(name), Some(abs)) =
                        (&u.name, tree.absolute(&path, &u.path, &aliases))
                    {
                        aliases.insert(name.clone(), abs);
                    }
                }
            }
            tree.files.get_mut(&path).unwrap().aliases = aliases;
        }
        tree
    }

    /// The absolute path that `path`, written in `file`, means; None for other crates' and
    /// local names (`std::…`, `Self::…`, a variant of an enum defined there).
    fn absolute(
        &self,
        file: &Path,
        path: &[String],
        aliases: &BTreeMap<String, Abs>,
    ) -> Option<Abs> {
        let f = &self.files[file];
        let (first, rest) = path.split_first()?;
        let (krate, mut segments) = match first.as_str() {
            "crate" => (f.krate, Vec::new()),
            "self" | "super" => (f.krate, f.module.clone()),
            name if f.children.contains(name) => {
                (f.krate, f.module.iter().chain([first]).cloned().collect())
            }
            name => match self.crates.iter().position(|c| c.name == name) {
                Some(k) => (k, Vec::new()),
                None => aliases.get(name)?.clone(),
            },
        };
        let mut rest = rest.iter().peekable();
        if first == "super" {
            segments.pop();
            while rest.next_if(|s| *s == "super").is_some() {
                segments.pop();
            }
        }
        segments.extend(rest.cloned());
        Some((krate, segments))
    }

    /// The file that defines what `abs` names (a module: its own file), re-exports followed.
    fn resolve(&self, abs: &Abs, depth: usize) -> Option<&Path> {
        let (krate, segments) = abs;
        let n = (0..=segments.len())
            .rev()
            .find(|&n| self.modules.contains_key(&(*krate, segments[..n].to_vec())))?;
        let file = &self.modules[&(*krate, segments[..n].to_vec())];
        let Some(item) = segments.get(n) else {
            return Some(file);
        };
        let f = &self.files[file];
        if depth > 8 || defines(&f.body, item) {
            return Some(file);
        }
        for u in f.uses.iter().filter(|u| u.public) {
            let Some(mut target) = self.absolute(file, &u.path, &f.aliases) else {
                continue;
            };
            let glob = u.name.is_none();
            if glob {
                target.1.push(item.clone());
            } else if u.name.as_deref() != Some(item) {
                continue;
            }
            target.1.extend(segments[n + 1..].iter().cloned());
            let found = self.resolve(&target, depth + 1);
            // A glob re-exports the item only where the module it names has it.
            if let Some(found) = found.filter(|&t| !glob || self.has(t, item)) {
                return Some(found);
            }
        }
        Some(file)
    }

    /// Whether `file` defines `item` or is the module `item`.
    fn has(&self, file: &Path, item: &str) -> bool {
        let f = &self.files[file];
        defines(&f.body, item) || f.module.last().is_some_and(|m| m == item)
    }

    /// The files whose items `file`'s code uses (itself left out).
    pub fn imports(&self, file: &Path) -> BTreeSet<PathBuf> {
        let f = &self.files[file];
        let mut targets = Vec::new();
        for u in &f.uses {
            let Some(abs) = self.absolute(file, &u.path, &f.aliases) else {
                continue;
            };
            let names_module = self.modules.contains_key(&abs);
            let re_export_only = u.public && u.name.as_deref().is_none_or(|n| !names(&f.body, n));
            if !re_export_only && (u.name.is_none() || !names_module) {
                targets.push(abs);
            }
        }
        for path in paths(&f.body) {
            targets.extend(self.absolute(file, &path, &f.aliases));
        }
        targets
            .iter()
            .filter_map(|abs| self.resolve(abs, 0))
            .filter(|&t| t != file)
            .map(Path::to_path_buf)
            .collect()
    }

    /// The top-level module of a file (`scene` for `scene/validate.rs`); None for crate roots.
    pub fn top_module(&self, file: &Path) -> Option<&str> {
        self.files[file].module.first().map(String::as_str)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn code_drops_comments_literals_and_tests_and_keeps_what_follows_a_test_module() {
        let text = "use a::b; // use c::d;\n/* x /* nested */ y */ fn f() { let s = \"crate::e\"; \
                    let r = r#\"}\"#; let c = '{'; let q = '\\''; }\n#[cfg(test)]\nmod tests { \
                    fn t() { let _ = \"}\"; } }\nfn g<'a>(x: &'a str) {}\n";
        let code = code(text);
        assert!(!code.contains("c::d") && !code.contains("nested"), "{code}");
        assert!(
            !code.contains("crate::e") && !code.contains("tests"),
            "{code}"
        );
        assert!(code.contains("fn g<'a>(x: &'a str) {}"), "{code}");
        assert_eq!(code.matches('\n').count(), text.matches('\n').count() - 1);
    }

    #[test]
    fn use_trees_expand_with_groups_self_aliases_and_globs() {
        let (items, body) =
            uses("pub(crate) use crate::{a::{self, b as c}, d::*};\nuse super::e;\nfn f() {}");
        let got: Vec<(String, Option<&str>, bool)> = items
            .iter()
            .map(|u| (u.path.join("::"), u.name.as_deref(), u.public))
            .collect();
        assert_eq!(
            got,
            [
                ("crate::a".to_string(), Some("a"), true),
                ("crate::a::b".to_string(), Some("c"), true),
                ("crate::d".to_string(), None, true),
                ("super::e".to_string(), Some("e"), false),
            ]
        );
        assert_eq!(body.trim(), "fn f() {}");
    }

    #[test]
    fn a_name_is_used_where_it_is_not_a_path_segment_field_or_method() {
        assert!(names("fn f() { run(1); }", "run"));
        assert!(names("let x: Run = y;", "Run"));
        assert!(!names("crate::run::go(); x.run(); running();", "run"));
    }

    #[test]
    fn paths_are_read_from_their_start_and_cut_at_generics() {
        let got = paths("let x = crate::a::b::<T>::c(super::d); y::z; Self::new();");
        let got: Vec<String> = got.iter().map(|p| p.join("::")).collect();
        assert_eq!(got, ["crate::a::b", "super::d", "y::z", "Self::new"]);
    }

    /// A tree of one crate `k` at `/k` from (file, text) pairs.
    fn tree(files: &[(&str, &str)]) -> Tree {
        let crates = vec![Crate {
            name: "k",
            dir: PathBuf::from("/k"),
            root: PathBuf::from("/k/lib.rs"),
        }];
        let texts = files
            .iter()
            .map(|(f, t)| (Path::new("/k").join(f), t.to_string()))
            .collect();
        Tree::new(crates, texts)
    }

    fn imports(tree: &Tree, file: &str) -> Vec<String> {
        tree.imports(&Path::new("/k").join(file))
            .iter()
            .map(|p| p.strip_prefix("/k").unwrap().display().to_string())
            .collect()
    }

    #[test]
    fn paths_resolve_to_the_file_that_defines_the_item() {
        let t = tree(&[
            ("lib.rs", "mod a; mod x;"),
            ("a/mod.rs", "pub mod b; pub fn f() {}"),
            ("a/b.rs", "pub struct C;"),
            (
                "x.rs",
                "use crate::a::b::C;\nfn g() { crate::a::f(); }\nmod y;",
            ),
            ("x/y.rs", "use super::super::a;\nfn h() { a::b::C; }"),
        ]);
        assert_eq!(imports(&t, "x.rs"), ["a/b.rs", "a/mod.rs"]);
        assert_eq!(imports(&t, "x/y.rs"), ["a/b.rs"], "through a module alias");
        assert!(imports(&t, "lib.rs").is_empty(), "`mod x;` is no import");
    }

    #[test]
    fn re_exports_lead_to_the_defining_file_and_import_nothing_themselves() {
        let t = tree(&[
            ("lib.rs", "mod a;"),
            ("a/mod.rs", "mod b; mod c;\npub use b::B;\npub use c::*;"),
            ("a/b.rs", "use super::C;\npub struct B;"),
            ("a/c.rs", "pub struct C;"),
        ]);
        assert_eq!(
            imports(&t, "a/b.rs"),
            ["a/c.rs"],
            "through a glob re-export"
        );
        assert!(imports(&t, "a/mod.rs").is_empty());
        let uses_its_export = tree(&[
            ("lib.rs", "mod a;"),
            ("a/mod.rs", "mod b;\npub use b::B;\npub struct P(B);"),
            ("a/b.rs", "use super::P;\npub struct B;"),
        ]);
        assert_eq!(imports(&uses_its_export, "a/mod.rs"), ["a/b.rs"]);
        assert_eq!(imports(&uses_its_export, "a/b.rs"), ["a/mod.rs"]);
    }

    #[test]
    fn other_crates_are_reached_through_their_names_and_re_exports() {
        let crates = vec![
            Crate {
                name: "core",
                dir: PathBuf::from("/c"),
                root: PathBuf::from("/c/lib.rs"),
            },
            Crate {
                name: "app",
                dir: PathBuf::from("/a"),
                root: PathBuf::from("/a/lib.rs"),
            },
        ];
        let texts = [
            ("/c/lib.rs", "pub mod s;"),
            ("/c/s.rs", "pub struct S;"),
            ("/a/lib.rs", "pub use core::s;\npub mod u;"),
            ("/a/u.rs", "fn f() { crate::s::S; }"),
        ];
        let texts = texts
            .iter()
            .map(|(f, t)| (PathBuf::from(f), t.to_string()))
            .collect();
        let t = Tree::new(crates, texts);
        let got: Vec<PathBuf> = t.imports(Path::new("/a/u.rs")).into_iter().collect();
        assert_eq!(got, [PathBuf::from("/c/s.rs")]);
        assert!(t.imports(Path::new("/a/lib.rs")).is_empty());
    }
}
