//! ARCHITECTURE.md's map held to the tree (issue 51): every source file of every crate is
//! named there (by its file name, its path in `src/`, or its module path such as
//! `contract::tables`), and every doc it cites exists.

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
