//! The crate's modules form layers (see the crate docs): a module may use its
//! own layer and those below, never one above, and only tests may call the
//! f64 reference. This reads `src/`, collects every `crate::`, `super::` and
//! `self::` path per file (comments and literals stripped, `#[cfg(test)]`
//! items told apart) and checks both rules, plus that no two production
//! modules of one layer import each other in a circle.
//!
//! Test code may use modules of its own layer in any direction (a kernel's
//! test compares with another kernel), so the circle check reads production
//! code only.

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

/// Top-level modules and their layers, bottom first. A new module must be
/// placed here before the test passes.
const LAYERS: &[(&str, usize)] = &[("gemm", 0), ("weights", 1), ("layers", 2), ("reference", 3), ("net", 4), ("train", 5)];

/// The one module that is the test oracle.
const ORACLE: &str = "reference";

#[test]
fn modules_import_only_their_own_layer_and_below() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    read_dir(&src, &src, &mut files);
    assert!(files.len() > 10, "read {} files from {}", files.len(), src.display());
    let problems = check(&files);
    assert!(problems.is_empty(), "dem-nn's modules break the layering:\n{}", problems.join("\n"));
}

/// The checker itself: an upward import, a production call of the reference
/// and a circle inside a layer are each caught, in every spelling; comments,
/// literals and test items are not mistaken for production imports.
#[test]
fn the_checker_catches_each_kind_of_break() {
    const BASE: [(&str, &str); 10] = [
        ("lib.rs", "pub mod gemm; pub mod layers; pub mod net; pub mod reference; pub mod train; pub mod weights;"),
        ("gemm.rs", ""),
        ("weights.rs", ""),
        ("layers/mod.rs", "pub mod conv; pub mod norm;"),
        ("layers/conv.rs", ""),
        ("layers/norm.rs", ""),
        ("reference.rs", "use crate::layers::conv::same_pad; use crate::weights::LEAK;"),
        ("net/mod.rs", "pub mod generator;"),
        ("net/generator.rs", "use crate::layers::conv; use super::super::weights::Arch;"),
        ("train/data.rs", "use crate::net::generator::Generator;"),
    ];
    let check_with = |changed: &[(&str, &str)]| {
        let mut files: Vec<(String, String)> = BASE.iter().map(|(p, s)| (p.to_string(), s.to_string())).collect();
        for (p, s) in changed {
            files.retain(|f| f.0 != *p);
            files.push((p.to_string(), s.to_string()));
        }
        check(&files)
    };
    let one = |changed: &[(&str, &str)], word: &str| {
        let p = check_with(changed);
        assert!(p.len() == 1 && p[0].contains(word), "{changed:?}: want one problem with {word:?}, got {p:?}");
    };
    assert_eq!(check_with(&[]), Vec::<String>::new());
    for upward in [
        "use crate::net::generator::GRID;",
        "use crate::{gemm, net};",
        "use crate::{gemm::{self, Mat}, layers::conv::ConvGeom as G};",
        "fn f() -> usize { crate::train::data::X }",
        "mod inner { use super::super::layers; }",
        "#[cfg(test)]\nmod tests {\n    use crate::net;\n}",
    ] {
        one(&[("weights.rs", upward)], "above it");
    }
    for oracle in [
        "use crate::reference;",
        "fn f() { let _ = crate::reference::generator(); }",
        "#[cfg(test)]\nfn g() -> [u8; 1] { [0] }\nuse crate::reference;",
        "#[cfg(test)]\nuse std::{fs, io};\nuse super::super::reference::generator;",
    ] {
        one(&[("layers/conv.rs", oracle)], "test oracle");
    }
    for fine in [
        "// use crate::net;\n/* crate::train /* nested */ */ const S: &str = \"crate::net\"; const R: &str = r#\"crate::net\"#;",
        "const C: char = '{'; const Q: char = '\\''; pub(crate) fn f<'a>(x: &'a u8) -> &'a u8 { x }",
        "#[cfg(test)]\nmod tests {\n    use super::*;\n    use crate::reference;\n}",
        "#[cfg(test)]\nuse crate::reference::generator;",
        "use crate::layers::norm; use self::inner::X; mod inner { use super::*; }",
    ] {
        assert_eq!(check_with(&[("layers/conv.rs", fine)]), Vec::<String>::new(), "{fine}");
    }
    one(&[("layers/norm.rs", "use crate::layers::conv::X;"), ("layers/conv.rs", "use super::norm::Y;")], "circle");
    one(&[("extra.rs", "")], "no layer");
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
fn module_of(rel: &str) -> Vec<String> {
    let rel = rel.strip_suffix(".rs").expect(".rs file");
    let mut segs: Vec<String> = rel.split('/').map(str::to_string).collect();
    if matches!(segs.last().map(String::as_str), Some("mod" | "lib")) {
        segs.pop();
    }
    segs
}

fn layer(top: &str) -> Option<usize> {
    LAYERS.iter().find(|(m, _)| *m == top).map(|(_, l)| *l)
}

/// One reference from a file to a module: the target, the line, and whether
/// it sits in a `#[cfg(test)]` item.
struct Edge {
    to: Vec<String>,
    line: usize,
    test: bool,
}

/// Every layering break in `files` (path under `src/`, text), one line each.
fn check(files: &[(String, String)]) -> Vec<String> {
    let modules: Vec<Vec<String>> = files.iter().map(|(p, _)| module_of(p)).collect();
    let mut problems = Vec::new();
    let mut graph: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for ((path, text), from) in files.iter().zip(&modules) {
        let Some(top) = from.first() else { continue };
        let Some(from_layer) = layer(top) else {
            problems.push(format!("{path}: module `{top}` has no layer in LAYERS"));
            continue;
        };
        for e in edges(from, text) {
            // The longest module (file) the path names; an item's path ends in it.
            let to = modules.iter().filter(|m| !m.is_empty() && e.to.starts_with(m)).max_by_key(|m| m.len());
            let Some(to) = to else {
                problems.push(format!("{path}:{}: `crate::{}` names no module with a layer", e.line, e.to.join("::")));
                continue;
            };
            if to == from {
                continue;
            }
            let to_layer = layer(&to[0]).unwrap_or(usize::MAX);
            let name = to.join("::");
            if to[0] == ORACLE && top != ORACLE {
                if !e.test {
                    problems.push(format!("{path}:{}: production code uses the test oracle `{name}`", e.line));
                }
            } else if to_layer > from_layer {
                problems.push(format!(
                    "{path}:{}: `{}` (layer {from_layer}) uses `{name}` (layer {to_layer}) above it",
                    e.line,
                    from.join("::")
                ));
            } else if !e.test {
                graph.entry(from.join("::")).or_default().push(name);
            }
        }
    }
    for circle in circles(&graph) {
        problems.push(format!("modules import each other in a circle: {}", circle.join(" -> ")));
    }
    problems
}

/// The circles of a directed graph, each once (found by depth-first search).
fn circles(graph: &BTreeMap<String, Vec<String>>) -> Vec<Vec<String>> {
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
fn edges(file: &[String], text: &str) -> Vec<Edge> {
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
