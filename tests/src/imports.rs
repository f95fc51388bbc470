//! The import graph of a crate, read from its source text: which file names items of which
//! other file (`use crate::…`, `use super::…`, paths in code such as `crate::a::f()`), so that
//! `tests/structure.rs` can keep every crate's modules in a strict hierarchy — no import cycle
//! between the top-level modules of a crate, and none between its files (issue 28, "one
//! house").
//!
//! What counts: paths in non-test code that start with `crate`, `super` or `self`, resolved to
//! the file of the module they name — or, when the path names an item a module re-exports with
//! `pub use`, to the file that re-export points at (followed a few hops). What does not: code
//! in `#[cfg(test)]` modules (a test may reach anywhere), comments and string literals, the
//! crate root (`lib.rs`/`main.rs`: the index that declares the modules), `mod x;`
//! declarations, and other crates. This is a reading of text, not of the compiler's name
//! resolution: a glob import (`use super::*`) names its module, and a name defined in an
//! inline non-test module is taken as its file's.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path inside a crate (`["printer", "host"]`); the root is empty.
pub type ModPath = Vec<String>;

/// One crate's files and the edges between them.
#[derive(Debug, Default)]
pub struct Graph {
    /// Each source file (relative to the crate's `src`) and its module path.
    pub files: BTreeMap<PathBuf, ModPath>,
    /// `from → to`: `from` names an item of `to` (both relative paths, never the same).
    pub edges: BTreeSet<(PathBuf, PathBuf)>,
}

/// Reads every `.rs` file below `src` (a crate's source folder).
pub fn read_crate(src: &Path) -> std::io::Result<Graph> {
    let mut files = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir)? {
            let p = entry?.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                let rel = p.strip_prefix(src).unwrap_or(&p).to_path_buf();
                files.insert(rel.clone(), mod_path_of(&rel));
            }
        }
    }
    let mut texts = BTreeMap::new();
    let mut test_only = BTreeSet::new();
    for rel in files.keys() {
        let text = strip_comments_and_strings(&std::fs::read_to_string(src.join(rel))?);
        // `#[cfg(test)] mod x;`: the file of `x` is a test's (a test may reach anywhere).
        for (at, _) in text.match_indices("#[cfg(test)]") {
            let after = text[at + "#[cfg(test)]".len()..].trim_start();
            let Some(decl) = after.strip_prefix("mod ") else {
                continue;
            };
            let Some(name) = decl.split(';').next().map(str::trim) else {
                continue;
            };
            if name.chars().all(|c| c.is_alphanumeric() || c == '_') {
                let mut m = files[rel].clone();
                m.push(name.to_string());
                test_only.insert(m);
            }
        }
        texts.insert(rel.clone(), strip_tests(&text));
    }
    files.retain(|_, m| !test_only.contains(m));
    texts.retain(|f, _| files.contains_key(f));
    let by_mod: BTreeMap<ModPath, PathBuf> =
        files.iter().map(|(f, m)| (m.clone(), f.clone())).collect();
    let reexports: BTreeMap<PathBuf, BTreeMap<String, ModPath>> = texts
        .iter()
        .map(|(f, t)| (f.clone(), pub_uses(t, &files[f])))
        .collect();
    let mut edges = BTreeSet::new();
    for (f, text) in &texts {
        if files[f].is_empty() {
            continue; // the crate root
        }
        for path in paths_in(text) {
            let Some(abs) = absolute(&path, &files[f]) else {
                continue;
            };
            if let Some(to) = resolve(&abs, &by_mod, &reexports, 4) {
                if &to != f && !files[&to].is_empty() {
                    edges.insert((f.clone(), to));
                }
            }
        }
    }
    Ok(Graph { files, edges })
}

/// `a/b.rs` → `[a, b]`, `a/mod.rs` → `[a]`, `lib.rs`/`main.rs` → `[]`.
fn mod_path_of(rel: &Path) -> ModPath {
    let mut parts: Vec<String> = rel
        .iter()
        .map(|c| c.to_string_lossy().into_owned())
        .collect();
    if let Some(last) = parts.pop() {
        let stem = last.trim_end_matches(".rs").to_string();
        if parts.is_empty() && (stem == "lib" || stem == "main") {
            return Vec::new();
        }
        if stem != "mod" {
            parts.push(stem);
        }
    }
    parts
}

/// A path as written (`super::x::Y`) made absolute from the module `here`; `None` for paths
/// that leave the crate.
fn absolute(path: &[String], here: &ModPath) -> Option<ModPath> {
    let mut out: ModPath;
    let mut rest = path;
    match path.first().map(String::as_str) {
        Some("crate") => {
            out = Vec::new();
            rest = &path[1..];
        }
        Some("self") => {
            out = here.clone();
            rest = &path[1..];
        }
        Some("super") => {
            out = here.clone();
            while rest.first().is_some_and(|s| s == "super") {
                out.pop()?;
                rest = &rest[1..];
            }
        }
        _ => return None,
    }
    out.extend(rest.iter().cloned());
    Some(out)
}

/// The file an absolute path names: the longest prefix that is a module, followed through
/// `pub use` re-exports of the next name (up to `hops` times).
fn resolve(
    abs: &ModPath,
    by_mod: &BTreeMap<ModPath, PathBuf>,
    reexports: &BTreeMap<PathBuf, BTreeMap<String, ModPath>>,
    hops: usize,
) -> Option<PathBuf> {
    let mut n = abs.len();
    loop {
        if let Some(f) = by_mod.get(&abs[..n]) {
            if hops > 0 && n < abs.len() {
                if let Some(target) = reexports.get(f).and_then(|r| r.get(&abs[n])) {
                    let mut next = target.clone();
                    next.extend(abs[n + 1..].iter().cloned());
                    if next != *abs {
                        if let Some(t) = resolve(&next, by_mod, reexports, hops - 1) {
                            return Some(t);
                        }
                    }
                }
            }
            return Some(f.clone());
        }
        if n == 0 {
            return None;
        }
        n -= 1;
    }
}

/// The `pub use` (also `pub(crate)`/`pub(super)` use) bindings of a file: name → absolute path.
fn pub_uses(text: &str, here: &ModPath) -> BTreeMap<String, ModPath> {
    let mut out = BTreeMap::new();
    let toks = tokens(text);
    let mut i = 0;
    while i < toks.len() {
        if toks[i] == "pub" {
            let mut j = i + 1;
            if toks.get(j).is_some_and(|t| t == "(") {
                while j < toks.len() && toks[j] != ")" {
                    j += 1;
                }
                j += 1;
            }
            if toks.get(j).is_some_and(|t| t == "use") {
                let (paths, end) = use_tree(&toks, j + 1);
                for (p, alias) in paths {
                    if let (Some(abs), Some(name)) =
                        (absolute(&p, here), alias.or(p.last().cloned()))
                    {
                        if name != "*" && name != "self" {
                            out.insert(name, abs);
                        }
                    }
                }
                i = end;
                continue;
            }
        }
        i += 1;
    }
    out
}

/// Every `crate`/`super`/`self` path of the text: in `use` trees and in code.
fn paths_in(text: &str) -> Vec<Vec<String>> {
    let toks = tokens(text);
    let mut out = Vec::new();
    let mut i = 0;
    while i < toks.len() {
        if toks[i] == "use" {
            let (paths, end) = use_tree(&toks, i + 1);
            out.extend(paths.into_iter().map(|(p, _)| p));
            i = end;
            continue;
        }
        let t = toks[i].as_str();
        let starts = matches!(t, "crate" | "super" | "self")
            && toks.get(i + 1).is_some_and(|n| n == "::")
            && (i == 0 || toks[i - 1] != "::");
        if starts {
            let mut p = vec![t.to_string()];
            let mut j = i + 1;
            while toks.get(j).is_some_and(|n| n == "::")
                && toks.get(j + 1).is_some_and(|n| is_ident(n))
            {
                p.push(toks[j + 1].clone());
                j += 2;
            }
            out.push(p);
            i = j;
            continue;
        }
        i += 1;
    }
    out
}

/// The paths a `use` tree starting at token `i` names, each with its `as` alias; and the index
/// after its `;`.
/// A path a `use` names, with its `as` alias.
type Named = (Vec<String>, Option<String>);

fn use_tree(toks: &[String], i: usize) -> (Vec<Named>, usize) {
    fn walk(toks: &[String], mut i: usize, prefix: &[String], out: &mut Vec<Named>) -> usize {
        let mut path = prefix.to_vec();
        while i < toks.len() {
            match toks[i].as_str() {
                "::" => i += 1,
                "{" => {
                    i += 1;
                    loop {
                        i = walk(toks, i, &path, out);
                        match toks.get(i).map(String::as_str) {
                            Some(",") => i += 1,
                            Some("}") => return i + 1,
                            _ => return i,
                        }
                        if toks.get(i).is_some_and(|t| t == "}") {
                            return i + 1;
                        }
                    }
                }
                "as" => {
                    let alias = toks.get(i + 1).cloned();
                    out.push((path, alias));
                    return i + 2;
                }
                "," | "}" | ";" => {
                    if path.len() > prefix.len() {
                        out.push((path, None));
                    }
                    return i;
                }
                t => {
                    path.push(t.to_string());
                    i += 1;
                }
            }
        }
        i
    }
    let mut out = Vec::new();
    let mut j = walk(toks, i, &[], &mut out);
    while j < toks.len() && toks[j] != ";" {
        j += 1;
    }
    (out, j + 1)
}

fn is_ident(t: &str) -> bool {
    t.chars()
        .next()
        .is_some_and(|c| c.is_alphabetic() || c == '_')
}

/// Identifiers and the punctuation that matters here (`::` as one token).
fn tokens(text: &str) -> Vec<String> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_alphanumeric() || c == b'_' || c >= 0x80 {
            let s = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] >= 0x80) {
                i += 1;
            }
            out.push(String::from_utf8_lossy(&b[s..i]).into_owned());
        } else if c == b':' && b.get(i + 1) == Some(&b':') {
            out.push("::".into());
            i += 2;
        } else if c.is_ascii_whitespace() {
            i += 1;
        } else {
            out.push((c as char).to_string());
            i += 1;
        }
    }
    out
}

/// The text with comments, string and char literals blanked (line structure kept).
fn strip_comments_and_strings(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == b'\n' {
                        out.push(b'\n');
                    }
                    i += 1;
                }
            }
        } else if c == b'r' && matches!(b.get(i + 1), Some(b'"') | Some(b'#')) && raw_start(b, i) {
            // r"…" / r#"…"#
            let mut j = i + 1;
            let mut hashes = 0;
            while b.get(j) == Some(&b'#') {
                hashes += 1;
                j += 1;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == b'"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&b'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            out.extend_from_slice(b"\"\"");
            i = j;
        } else if c == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.extend_from_slice(b"\"\"");
        } else if c == b'\'' {
            // A char literal ('a', '\n', '\u{..}') or a lifetime ('a): skip only literals.
            let lit = matches!(
                (b.get(i + 1), b.get(i + 2)),
                (Some(b'\\'), _) | (Some(_), Some(b'\''))
            );
            if lit {
                i += 1;
                while i < b.len() && b[i] != b'\'' {
                    if b[i] == b'\\' {
                        i += 1;
                    }
                    i += 1;
                }
                i += 1;
                out.extend_from_slice(b"' '");
            } else {
                out.push(c);
                i += 1;
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Whether `r` at `i` starts a raw string (not the end of an identifier such as `for`).
fn raw_start(b: &[u8], i: usize) -> bool {
    i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// The text without its `#[cfg(test)]` items (a `mod … { … }` or `mod …;`, a `use`, an `fn`).
fn strip_tests(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let after = &rest[at + "#[cfg(test)]".len()..];
        // The item ends at its first `;` before any `{`, or at the `}` matching its first `{`.
        let semi = after.find(';');
        let brace = after.find('{');
        let end = match (semi, brace) {
            (Some(s), Some(b)) if s < b => s + 1,
            (_, Some(b)) => {
                let mut depth = 0usize;
                let mut end = after.len();
                for (k, ch) in after[b..].char_indices() {
                    match ch {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = b + k + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                end
            }
            (Some(s), None) => s + 1,
            (None, None) => after.len(),
        };
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// The groups of files (or modules) that import one another, directly or around a loop:
/// strongly connected components of more than one node, each sorted.
pub fn cycles<T: Ord + Clone>(edges: &BTreeSet<(T, T)>) -> Vec<Vec<T>> {
    let nodes: BTreeSet<T> = edges
        .iter()
        .flat_map(|(a, b)| [a.clone(), b.clone()])
        .collect();
    let adj = |n: &T| -> Vec<T> {
        edges
            .iter()
            .filter(|(a, _)| a == n)
            .map(|(_, b)| b.clone())
            .collect()
    };
    // Reachability closure (the graphs are small: a few hundred files).
    let mut reach: BTreeMap<T, BTreeSet<T>> = BTreeMap::new();
    for n in &nodes {
        let mut seen = BTreeSet::new();
        let mut stack = adj(n);
        while let Some(m) = stack.pop() {
            if seen.insert(m.clone()) {
                stack.extend(adj(&m));
            }
        }
        reach.insert(n.clone(), seen);
    }
    let mut done = BTreeSet::new();
    let mut out = Vec::new();
    for n in &nodes {
        if done.contains(n) || !reach[n].contains(n) {
            continue;
        }
        let comp: Vec<T> = nodes
            .iter()
            .filter(|m| reach[n].contains(*m) && reach[*m].contains(n))
            .cloned()
            .collect();
        done.extend(comp.iter().cloned());
        out.push(comp);
    }
    out
}

/// The top-level module edges of a crate (`a → b` when a file of module `a` names an item of
/// module `b`), for [`cycles`].
pub fn module_edges(g: &Graph) -> BTreeSet<(String, String)> {
    g.edges
        .iter()
        .filter_map(|(a, b)| {
            let (ma, mb) = (g.files[a].first()?, g.files[b].first()?);
            (ma != mb).then(|| (ma.clone(), mb.clone()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Vec<String> {
        s.split("::").map(String::from).collect()
    }

    #[test]
    fn use_trees_and_code_paths() {
        let t = "use crate::{a::X, b::{Y, c::Z as W}};\nfn f() { crate::d::g(); super::e::H; x::crate_y(); }";
        let got = paths_in(t);
        assert!(got.contains(&p("crate::a::X")));
        assert!(got.contains(&p("crate::b::Y")));
        assert!(got.contains(&p("crate::b::c::Z")));
        assert!(got.contains(&p("crate::d::g")));
        assert!(got.contains(&p("super::e::H")));
        assert_eq!(got.len(), 5, "{got:?}");
    }

    #[test]
    fn comments_strings_and_tests_are_not_imports() {
        let t = "// use crate::a;\n/* crate::b::X */ let s = \"crate::c::Y\";\n#[cfg(test)]\nmod tests { use crate::d::Z; }\nuse crate::e::V;";
        let got = paths_in(&strip_tests(&strip_comments_and_strings(t)));
        assert_eq!(got, vec![p("crate::e::V")]);
    }

    #[test]
    fn relative_paths() {
        let here = p("printer::host");
        assert_eq!(
            absolute(&p("super::Printer"), &here),
            Some(p("printer::Printer"))
        );
        assert_eq!(absolute(&p("self::x"), &here), Some(p("printer::host::x")));
        assert_eq!(absolute(&p("super::super::a"), &here), Some(p("a")));
        assert_eq!(absolute(&p("super::super::super::a"), &here), None);
        assert_eq!(mod_path_of(Path::new("printer/mod.rs")), p("printer"));
        assert_eq!(mod_path_of(Path::new("lib.rs")), Vec::<String>::new());
    }

    #[test]
    fn cycles_are_found() {
        let e: BTreeSet<(u8, u8)> = [(1, 2), (2, 3), (3, 1), (3, 4), (5, 5)].into();
        assert_eq!(cycles(&e), vec![vec![1, 2, 3], vec![5]]);
        let dag: BTreeSet<(u8, u8)> = [(1, 2), (2, 3), (1, 3)].into();
        assert!(cycles(&dag).is_empty());
    }
}
