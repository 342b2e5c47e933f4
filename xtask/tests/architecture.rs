//! ARCHITECTURE.md's map held to the tree (issue 51): every source file of every crate is
//! named there (by its file name, its path in `src/`, or its module path such as
//! `contract::tables`), and every doc it cites exists; and no function outside tests is
//! longer than a screen.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("a source folder") {
        let p = e.expect("an entry").path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

#[test]
fn the_map_names_every_module_and_every_doc_it_cites_exists() {
    let root = root();
    let map = std::fs::read_to_string(root.join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let mut unnamed = Vec::new();
    for krate in ["ingest", "align", "adjust", "report", "xtask", "fixtures"] {
        let src = root.join(krate).join("src");
        let mut files = Vec::new();
        sources(&src, &mut files);
        assert!(!files.is_empty(), "{krate} has sources");
        for f in files {
            let rel = f
                .strip_prefix(&src)
                .expect("under src")
                .to_string_lossy()
                .into_owned();
            let name = f
                .file_name()
                .expect("a name")
                .to_string_lossy()
                .into_owned();
            let module = rel.trim_end_matches(".rs").replace('/', "::");
            let named = map.contains(&format!("`{rel}`"))
                || map.contains(&format!("`{name}`"))
                || map.contains(&format!("{name}`"))
                || map.contains(&format!("`{module}`"))
                || map.contains(&format!("`{module}"));
            if !named {
                unnamed.push(format!("{krate}/src/{rel}"));
            }
        }
    }
    assert!(
        unnamed.is_empty(),
        "ARCHITECTURE.md does not name: {unnamed:#?}"
    );
    let mut missing = Vec::new();
    for (i, _) in map.match_indices("docs/") {
        let cited: String = map[i..]
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '/' | '-' | '_' | '.'))
            .collect();
        let cited = cited.trim_end_matches('.');
        if cited.ends_with(".md") && !root.join(cited).is_file() {
            missing.push(cited.to_owned());
        }
    }
    assert!(missing.is_empty(), "cited and missing: {missing:?}");
}

/// The functions of `text` before its `#[cfg(test)]` module longer than `limit` lines, from
/// the line naming them to their closing brace: (1-based line, name, lines).
fn long_functions(text: &str, limit: usize) -> Vec<(usize, String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let end = lines
        .iter()
        .position(|l| l.starts_with("#[cfg(test)]"))
        .unwrap_or(lines.len());
    let mut out = Vec::new();
    for (i, l) in lines[..end].iter().enumerate() {
        let body = l.trim_start();
        let indent = &l[..l.len() - body.len()];
        let mut rest = body;
        while let Some(r) = ["pub(crate) ", "pub(super) ", "pub ", "const ", "async "]
            .iter()
            .find_map(|p| rest.strip_prefix(p))
        {
            rest = r;
        }
        let Some(signature) = rest.strip_prefix("fn ") else {
            continue;
        };
        // A declaration without a body, or a body on the same line.
        if l.trim_end().ends_with(';') || (l.contains('{') && l.trim_end().ends_with('}')) {
            continue;
        }
        let closing = format!("{indent}}}");
        let Some(last) = lines[i..end].iter().position(|m| m.trim_end() == closing) else {
            continue;
        };
        if last + 1 > limit {
            let name: String = signature
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            out.push((i + 1, name, last + 1));
        }
    }
    out
}

/// No function outside tests is longer than a screen, 80 lines (issue 51), in any crate;
/// and the scan finds one that is.
#[test]
fn no_function_outside_tests_is_over_80_lines() {
    let root = root();
    let mut long = Vec::new();
    for krate in ["ingest", "align", "adjust", "report", "xtask", "fixtures"] {
        let mut files = Vec::new();
        sources(&root.join(krate).join("src"), &mut files);
        for f in files {
            let text = std::fs::read_to_string(&f).expect("a source file");
            for (line, name, n) in long_functions(&text, 80) {
                long.push(format!("{}:{line} {name}: {n} lines", f.display()));
            }
        }
    }
    assert!(long.is_empty(), "over 80 lines:\n{}", long.join("\n"));
    let body = "    let x = 1;\n".repeat(80);
    let made = format!("pub(crate) fn long(\n    a: u8,\n) {{\n{body}}}\nfn short() {{}}\n");
    assert_eq!(long_functions(&made, 80), vec![(1, "long".to_owned(), 84)]);
    let tested = format!(
        "fn short() {{}}\n#[cfg(test)]\nmod tests {{\n    fn long() {{\n{body}    }}\n}}\n"
    );
    assert!(long_functions(&tested, 80).is_empty());
}
