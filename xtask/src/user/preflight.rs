//! init's draft read by check's own readers before it is written (issue 49): what check
//! would refuse, init says. The draft's `"FILL IN"` values are stood in for by values any
//! log passes (the benchmark's gravity, a unit, a time scale, a session kind that asks for
//! no theodolite log), the logs are trimmed into a scratch dataset as check trims them
//! (their ends kept, their middles blank, [`crate::user::check::trim`]), and check runs on it.
//! Where a value cannot be stood in for (a session's date or start: the times depend on
//! them), the draft is not checked, and init says which key waits.

use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// What stands in for a key's `"FILL IN"` while the draft is checked: None where no value
/// can (the logs' times depend on it).
fn stand_in(key: &str) -> Option<&'static str> {
    Some(match key {
        "g_abs_mgal" => "980000.0",
        "theodolite_unit" => "\"deg\"",
        "time_scale" => "\"UTC\"",
        "kind" => "\"survey\"",
        "reading_unit" => "\"count\"",
        "adc_columns" => "[1, 2, 3]",
        "thermometers" => "\"each\"",
        "offset_mgal" => "0.0",
        "scale" => "1.0",
        _ => return None,
    })
}

/// The draft `text` with every `"FILL IN"` stood in for, or the first key none can be.
fn stood_in(text: &str) -> Result<String, String> {
    let mark = format!("= {}", crate::user::init::FILL);
    text.lines()
        .map(|line| match line.split_once(&mark) {
            Some((key, _)) => {
                let key = key.trim();
                stand_in(key)
                    .map(|v| format!("{key} = {v}"))
                    .ok_or_else(|| key.to_owned())
            }
            None => Ok(line.to_owned()),
        })
        .collect::<Result<Vec<_>, _>>()
        .map(|lines| lines.join("\n") + "\n")
}

/// Check's verdict on the draft `text` of the dataset `dataset` (its logs `files` in raw/,
/// each with whether it is a binary log): the verdicts check prints when it refuses (its
/// paths the dataset's), empty when it reads every log; or the one line saying why the
/// draft could not be checked.
pub fn findings(dataset: &Path, files: &[(PathBuf, bool)], text: &str) -> Result<Vec<String>> {
    let draft = match stood_in(text) {
        Ok(d) => d,
        Err(key) => {
            return Ok(vec![format!(
                "the logs were not read as check reads them: `{key}` must be filled first \
                 (`cargo xtask check` reads them then)"
            )]);
        }
    };
    // As check's own scratch copy: a folder of this process's under the system's temporary
    // one, removed however the check ends.
    let scratch = std::env::temp_dir().join(format!("gravcal-init-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let copy = scratch.join(dataset.file_name().unwrap_or_default());
    let checked = check_copy(dataset, &copy, files, &draft);
    let _ = std::fs::remove_dir_all(&scratch);
    let Some(out) = checked? else {
        return Ok(Vec::new());
    };
    let text = String::from_utf8_lossy(&out)
        .replace(&copy.display().to_string(), &dataset.display().to_string());
    // Its verdicts, not its account of every file (`cargo xtask check` prints that).
    Ok(text
        .lines()
        .filter_map(|l| l.strip_prefix("check: "))
        .filter(|l| !l.contains(" is valid: "))
        .map(str::to_owned)
        .collect())
}

/// Trims `files` of `dataset` into `copy` with the stood-in `draft` as its manifest and
/// checks it: None when check reads every log, else what it printed.
fn check_copy(
    dataset: &Path,
    copy: &Path,
    files: &[(PathBuf, bool)],
    draft: &str,
) -> Result<Option<Vec<u8>>> {
    for (f, binary) in files {
        let rel = f.strip_prefix(dataset).unwrap_or(f);
        crate::user::check::trim(f, &copy.join(rel), *binary)?;
    }
    std::fs::write(copy.join("dataset.toml"), draft).context("writing the stood-in draft")?;
    let mut out = Vec::new();
    Ok((!crate::user::check::run(copy, &mut out)?).then_some(out))
}
