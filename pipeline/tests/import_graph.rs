//! No import circle between the modules of any workspace crate (the crates themselves cannot form one: Cargo
//! refuses a dependency cycle). An edge A → B is a path `crate::B…` or `super::…` (resolved to B) in A's
//! code outside its `#[cfg(test)]` part and outside comments; an edge between a module and its own ancestor
//! or descendant is the module tree itself, not an import, and is left out. The strongly connected
//! components of the remaining graph must all be single modules: every interface lives below its users.

mod common;
use common::{rust_files, workspace_root};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

const CRATES: [&str; 6] = ["ingest", "tracer", "optim", "workflow", "lab", "pipeline"];

/// `a/b.rs` and `a/b/mod.rs` → `["a", "b"]`; crate roots → `[]`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = rel.iter().map(|s| s.to_string_lossy().into_owned()).collect();
    if parts.last().is_some_and(|l| l == "mod") {
        parts.pop();
    }
    if parts.len() == 1 && (parts[0] == "lib" || parts[0] == "main") {
        parts.clear();
    }
    parts
}

/// The code of a file without its test module and without comments (string literals kept as they are).
fn code(text: &str) -> String {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let bytes = line.as_bytes();
        let mut in_str = false;
        let mut end = line.len();
        let mut i = 0;
        while i < bytes.len() {
            match bytes[i] {
                b'\\' if in_str => i += 1,
                b'"' => in_str = !in_str,
                b'/' if !in_str && bytes.get(i + 1) == Some(&b'/') => {
                    end = i;
                    break;
                }
                _ => {}
            }
            i += 1;
        }
        out.push_str(&line[..end]);
        out.push('\n');
    }
    out
}

fn ident_at(s: &str) -> Option<&str> {
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    (end > 0).then(|| &s[..end])
}

/// The paths named after `prefix::` at each occurrence in `code`, as segment lists (`a::{b, c::d}` → `a::b`,
/// `a::c::d`; `{x, y}` → `x`, `y`).
fn paths_after(code: &str, prefix: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find(prefix) {
        let before = rest[..at].chars().last();
        rest = &rest[at + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue; // e.g. `my_crate::` or `ensuper::`
        }
        collect_paths(rest, Vec::new(), &mut out);
    }
    out
}

fn collect_paths(s: &str, head: Vec<String>, out: &mut Vec<Vec<String>>) {
    let s = s.trim_start();
    if let Some(group) = s.strip_prefix('{') {
        let mut depth = 0;
        let mut start = 0;
        for (i, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    collect_paths(&group[start..i], head.clone(), out);
                    return;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    collect_paths(&group[start..i], head.clone(), out);
                    start = i + 1;
                }
                _ => {}
            }
        }
        return;
    }
    let Some(id) = ident_at(s) else {
        if !head.is_empty() {
            out.push(head);
        }
        return;
    };
    let mut head = head;
    head.push(id.to_owned());
    match s[id.len()..].strip_prefix("::") {
        Some(more) => collect_paths(more, head, out),
        None => out.push(head),
    }
}

fn is_prefix(a: &[String], b: &[String]) -> bool {
    a.len() <= b.len() && a == &b[..a.len()]
}

/// Module → the modules it imports, for one crate.
fn graph(krate: &str) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let src = workspace_root().join(krate).join("src");
    let files = rust_files(&src);
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_of(&src, f)).collect();
    let resolve = |path: &[String]| -> Vec<String> {
        let mut p = path.to_vec();
        while !p.is_empty() && !modules.contains(&p) {
            p.pop();
        }
        p
    };
    let mut g = BTreeMap::new();
    for f in &files {
        let m = module_of(&src, f);
        let is_mod_file = f.file_name().is_some_and(|n| n == "mod.rs" || n == "lib.rs" || n == "main.rs");
        let text = code(&std::fs::read_to_string(f).unwrap());
        let mut deps = BTreeSet::new();
        for p in paths_after(&text, "crate::") {
            deps.insert(resolve(&p));
        }
        for p in paths_after(&text, "super::") {
            // `super` of a `mod.rs` is the parent of its module; of `a/b.rs` it is `a`.
            let mut base = m.clone();
            if is_mod_file || !base.is_empty() {
                base.pop();
            }
            let mut segs = p.as_slice();
            while segs.first().is_some_and(|s| s == "super") {
                base.pop();
                segs = &segs[1..];
            }
            base.extend(segs.iter().cloned());
            deps.insert(resolve(&base));
        }
        deps.retain(|d| !is_prefix(d, &m) && !is_prefix(&m, d));
        g.insert(m, deps);
    }
    g
}

/// Tarjan's strongly connected components with more than one module.
fn cycles(g: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<&'a Vec<String>, usize>,
        low: BTreeMap<&'a Vec<String>, usize>,
        stack: Vec<&'a Vec<String>>,
        on: BTreeSet<&'a Vec<String>>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a Vec<String>) {
        let i = t.index.len();
        t.index.insert(v, i);
        t.low.insert(v, i);
        t.stack.push(v);
        t.on.insert(v);
        for w in t.g.get(v).into_iter().flatten() {
            let Some((w, _)) = t.g.get_key_value(w) else { continue };
            if !t.index.contains_key(w) {
                visit(t, w);
                let lw = t.low[w];
                let lv = t.low.get_mut(v).unwrap();
                *lv = (*lv).min(lw);
            } else if t.on.contains(w) {
                let iw = t.index[w];
                let lv = t.low.get_mut(v).unwrap();
                *lv = (*lv).min(iw);
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = t.stack.pop() {
                t.on.remove(w);
                comp.push(w.join("::"));
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t =
        T { g, index: BTreeMap::new(), low: BTreeMap::new(), stack: Vec::new(), on: BTreeSet::new(), out: Vec::new() };
    for v in g.keys() {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

#[test]
fn no_import_circle_in_any_crate() {
    let mut found = Vec::new();
    for krate in CRATES {
        for c in cycles(&graph(krate)) {
            found.push(format!("{krate}: {}", c.join(" ↔ ")));
        }
    }
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
}

#[test]
fn the_checker_sees_a_circle_and_reads_paths_as_rust_does() {
    let p = |s: &str| s.split("::").map(str::to_owned).collect::<Vec<_>>();
    let found = paths_after("use crate::a::{b, c::{d, e}};\nlet x = crate::f::g(1);", "crate::");
    assert_eq!(found, vec![p("a::b"), p("a::c::d"), p("a::c::e"), p("f::g")]);
    assert!(paths_after(&code("use my_crate::x; // crate::y"), "crate::").is_empty());
    assert_eq!(code("let s = \"//\"; // crate::x").trim(), "let s = \"//\";");
    let mut g = BTreeMap::new();
    g.insert(p("a"), BTreeSet::from([p("b")]));
    g.insert(p("b"), BTreeSet::from([p("c")]));
    g.insert(p("c"), BTreeSet::from([p("a")]));
    g.insert(p("d"), BTreeSet::from([p("a")]));
    assert_eq!(cycles(&g), vec![vec!["a".to_owned(), "b".to_owned(), "c".to_owned()]]);
}
