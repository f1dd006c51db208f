//! What a crate's modules import from each other, read from the source:
//! every `crate::`, `super::` and `self::` path per file, with comments and
//! literals stripped and `#[cfg(test)]` items told apart, and the circles
//! of the graph they make. The layering tests of dem-nn and the
//! workspace's no-circles test read the code through this.

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

/// Every `.rs` file under `src`, as (path under `src/`, text), sorted.
pub fn read_sources(src: &Path) -> Vec<(String, String)> {
    let mut files = Vec::new();
    read_dir(src, src, &mut files);
    files
}

fn read_dir(root: &Path, dir: &Path, out: &mut Vec<(String, String)>) {
    let mut entries: Vec<_> = fs::read_dir(dir).expect("src dir").map(|e| e.expect("dir entry").path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            read_dir(root, &p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            let rel = p.strip_prefix(root).expect("under src").to_string_lossy().replace('\\', "/");
            out.push((rel, fs::read_to_string(&p).expect("source file")));
        }
    }
}

/// The module path of a file under `src/`: `lib.rs` is the root, `a/mod.rs`
/// and `a.rs` are `a`, `a/b.rs` is `a::b`.
pub fn module_of(rel: &str) -> Vec<String> {
    let rel = rel.strip_suffix(".rs").expect(".rs file");
    let mut segs: Vec<String> = rel.split('/').map(str::to_string).collect();
    if matches!(segs.last().map(String::as_str), Some("mod" | "lib")) {
        segs.pop();
    }
    segs
}

/// One reference from a file to a module: the target, the line, and whether
/// it sits in a `#[cfg(test)]` item.
pub struct Edge {
    /// The module path named, from the crate root (an item's path ends in it).
    pub to: Vec<String>,
    /// Line of the reference.
    pub line: usize,
    /// Inside a `#[cfg(test)]` item (or a test-only file).
    pub test: bool,
}

/// The module (file) a path names: the longest of `modules` it starts
/// with, as an item's path ends in its module; `None` for the crate root
/// alone or a path outside every module.
pub fn module_named<'a>(modules: &'a [Vec<String>], path: &[String]) -> Option<&'a Vec<String>> {
    modules.iter().filter(|m| !m.is_empty() && path.starts_with(m)).max_by_key(|m| m.len())
}

/// The production imports between the modules (files) of one crate: for
/// each module, the modules it names outside test code, resolved to the
/// longest module the path names. A module's own items and its ancestors
/// and descendants are left out: a child reading its parent's types
/// (`super::X`) is nesting, not a circle.
pub fn production_graph(files: &[(String, String)]) -> BTreeMap<String, Vec<String>> {
    let modules: Vec<Vec<String>> = files.iter().map(|(p, _)| module_of(p)).collect();
    let mut graph: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for ((_, text), from) in files.iter().zip(&modules) {
        for e in edges(from, text).into_iter().filter(|e| !e.test) {
            let Some(to) = module_named(&modules, &e.to) else { continue };
            if to.starts_with(from) || from.starts_with(to) {
                continue;
            }
            let targets = graph.entry(from.join("::")).or_default();
            if !targets.contains(&to.join("::")) {
                targets.push(to.join("::"));
            }
        }
    }
    graph
}

/// The circles of a directed graph, each once (found by depth-first search).
pub fn circles(graph: &BTreeMap<String, Vec<String>>) -> Vec<Vec<String>> {
    fn visit<'a>(
        n: &'a str,
        graph: &'a BTreeMap<String, Vec<String>>,
        state: &mut BTreeMap<&'a str, bool>,
        stack: &mut Vec<&'a str>,
        out: &mut Vec<Vec<String>>,
    ) {
        state.insert(n, false);
        stack.push(n);
        for m in graph.get(n).into_iter().flatten() {
            match state.get(m.as_str()) {
                None => visit(m, graph, state, stack, out),
                Some(false) => {
                    let start = stack.iter().position(|s| s == m).expect("on the stack");
                    let mut c: Vec<String> = stack[start..].iter().map(|s| s.to_string()).collect();
                    c.push(m.clone());
                    out.push(c);
                }
                Some(true) => {}
            }
        }
        stack.pop();
        state.insert(n, true);
    }
    let (mut state, mut out) = (BTreeMap::new(), Vec::new());
    for n in graph.keys() {
        if !state.contains_key(n.as_str()) {
            visit(n, graph, &mut state, &mut Vec::new(), &mut out);
        }
    }
    out
}

/// A token of the stripped source and its line.
struct Tok {
    s: String,
    line: usize,
}

/// The module paths `text` (the file of module `file`) refers to through
/// `crate::`, `super::` or `self::`, as absolute paths from the crate root.
pub fn edges(file: &[String], text: &str) -> Vec<Edge> {
    let toks = tokens(&strip(text));
    let at = |i: usize| toks.get(i).map_or("", |t| t.s.as_str());
    let mut out = Vec::new();
    // Inline modules open at a brace depth: (name, depth inside).
    let mut inline: Vec<(String, usize)> = Vec::new();
    // The brace depth inside which a `#[cfg(test)]` item runs, or the
    // attribute's own depth while its item has not opened a brace yet.
    let mut test_from: Option<(usize, bool)> = None;
    let mut depth = 0;
    let mut nest = 0; // ( and [ inside a pending test item, where `;` ends nothing
    let mut whole_file_test = false;
    let mut i = 0;
    while i < toks.len() {
        let t = at(i);
        let attr = |neg: bool| {
            let o = if neg { 1 } else { 0 };
            at(i + 1 + o) == "["
                && at(i + 2 + o) == "cfg"
                && at(i + 3 + o) == "("
                && at(i + 4 + o) == "test"
                && at(i + 5 + o) == ")"
                && at(i + 6 + o) == "]"
        };
        if t == "#" && at(i + 1) == "!" && attr(true) {
            whole_file_test |= depth == 0 && inline.is_empty();
            i += 8;
            continue;
        }
        if t == "#" && attr(false) && test_from.is_none() {
            test_from = Some((depth, false));
            nest = 0;
            i += 7;
            continue;
        }
        match t {
            "{" => {
                depth += 1;
                if i >= 2 && at(i - 2) == "mod" {
                    inline.push((at(i - 1).to_string(), depth));
                }
                if let Some((d, false)) = test_from {
                    test_from = Some((d + 1, true));
                }
            }
            "}" => {
                if inline.last().is_some_and(|(_, d)| *d == depth) {
                    inline.pop();
                }
                if test_from == Some((depth, true)) {
                    test_from = None;
                }
                depth -= 1;
            }
            "(" | "[" => nest += 1,
            ")" | "]" => nest -= 1,
            ";" if nest == 0 && matches!(test_from, Some((d, false)) if d == depth) => test_from = None,
            _ => {}
        }
        let starts_path = (t == "crate" || t == "super" || t == "self") && at(i + 1) == "::" && (i == 0 || at(i - 1) != "::");
        if starts_path && !(t == "crate" && i > 0 && at(i - 1) == "$") {
            let mut base: Vec<String> =
                if t == "crate" { Vec::new() } else { file.iter().cloned().chain(inline.iter().map(|(n, _)| n.clone())).collect() };
            let line = toks[i].line;
            let test = whole_file_test || test_from.is_some();
            let mut j = i;
            while at(j) == "super" || at(j) == "self" || at(j) == "crate" {
                if at(j) == "super" {
                    base.pop();
                }
                j += 2; // the segment and its `::`
            }
            let mut paths = Vec::new();
            let end = use_tree(&toks, j, base, &mut paths);
            out.extend(paths.into_iter().map(|to| Edge { to, line, test }));
            i = end.max(i + 1);
            continue;
        }
        i += 1;
    }
    out
}

/// Parse a path or use tree at `toks[i]` under `prefix` (`a::b`, `a::{b, c::d}`,
/// `a::*`), push each full path (without `self` segments) and return the index
/// after it.
fn use_tree(toks: &[Tok], mut i: usize, mut prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let at = |i: usize| toks.get(i).map_or("", |t| t.s.as_str());
    if at(i) == "{" {
        i += 1;
        while i < toks.len() && at(i) != "}" {
            i = use_tree(toks, i, prefix.clone(), out);
            if at(i) == "," {
                i += 1;
            } else if at(i) != "}" {
                i += 1; // `as name` and the like
            }
        }
        return i + 1;
    }
    let ident = |s: &str| s.chars().next().is_some_and(|c| c.is_alphabetic() || c == '_');
    if ident(at(i)) {
        if at(i) != "self" {
            prefix.push(at(i).to_string());
        }
        if at(i + 1) == "::" && (at(i + 2) == "{" || at(i + 2) == "*" || ident(at(i + 2))) {
            return use_tree(toks, i + 2, prefix, out);
        }
        i += 1;
        if at(i) == "as" {
            i += 2;
        }
    } else if at(i) == "*" {
        i += 1;
    }
    out.push(prefix);
    i
}

/// Split stripped source into identifiers, `::` and single punctuation.
fn tokens(text: &str) -> Vec<Tok> {
    let c: Vec<char> = text.chars().collect();
    let (mut out, mut line, mut i) = (Vec::new(), 1, 0);
    while i < c.len() {
        if c[i] == '\n' {
            line += 1;
            i += 1;
        } else if c[i].is_whitespace() {
            i += 1;
        } else if c[i].is_alphanumeric() || c[i] == '_' {
            let s = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            out.push(Tok { s: c[s..i].iter().collect(), line });
        } else if c[i] == ':' && c.get(i + 1) == Some(&':') {
            out.push(Tok { s: "::".into(), line });
            i += 2;
        } else {
            out.push(Tok { s: c[i].to_string(), line });
            i += 1;
        }
    }
    out
}

/// The source with comments and string and character literals blanked (line
/// breaks kept), so only code is read.
fn strip(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let blank = |out: &mut String, s: &[char]| out.extend(s.iter().map(|&ch| if ch == '\n' { '\n' } else { ' ' }));
    let mut i = 0;
    while i < c.len() {
        let rest = &c[i..];
        let ident_before = i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_');
        let end = if rest.starts_with(&['/', '/']) {
            rest.iter().position(|&ch| ch == '\n').unwrap_or(rest.len())
        } else if rest.starts_with(&['/', '*']) {
            let (mut d, mut k) = (0, 0);
            while k < rest.len() {
                if rest[k..].starts_with(&['/', '*']) {
                    d += 1;
                    k += 2;
                } else if rest[k..].starts_with(&['*', '/']) {
                    d -= 1;
                    k += 2;
                    if d == 0 {
                        break;
                    }
                } else {
                    k += 1;
                }
            }
            k
        } else if !ident_before && (rest.starts_with(&['r', '"']) || rest.starts_with(&['r', '#']) || rest.starts_with(&['b', 'r'])) {
            // A raw string: r"..", r#".."#, br"..".
            let k0 = if rest[0] == 'b' { 2 } else { 1 };
            let hashes = rest[k0..].iter().take_while(|&&ch| ch == '#').count();
            if rest.get(k0 + hashes) != Some(&'"') {
                0
            } else {
                let close: Vec<char> = format!("\"{}", "#".repeat(hashes)).chars().collect();
                let body = k0 + hashes + 1;
                (body..rest.len()).find(|&k| rest[k..].starts_with(&close)).map_or(rest.len(), |k| k + close.len())
            }
        } else if rest[0] == '"' || (!ident_before && rest.starts_with(&['b', '"'])) {
            let mut k = if rest[0] == 'b' { 2 } else { 1 };
            while k < rest.len() && rest[k] != '"' {
                k += if rest[k] == '\\' { 2 } else { 1 };
            }
            k + 1
        } else if rest[0] == '\'' {
            // A character literal ('x', '\n', '\u{7b}'); otherwise a lifetime.
            if rest.get(1) == Some(&'\\') {
                rest.iter().skip(3).position(|&ch| ch == '\'').map_or(1, |k| k + 4)
            } else if rest.get(2) == Some(&'\'') {
                3
            } else {
                0
            }
        } else {
            0
        };
        if end == 0 {
            out.push(c[i]);
            i += 1;
        } else {
            let end = end.min(rest.len());
            blank(&mut out, &rest[..end]);
            i += end;
        }
    }
    out
}
