//! The general fitting command (docs/formats.md 7): its arguments and the CSV table it reads.

use crate::{Error, fit};
use std::path::{Path, PathBuf};

/// Arguments of the `fit` command (docs/formats.md section 7), shared by the stage binary and
/// `cargo xtask fit`.
#[derive(Clone, Debug, clap::Args)]
pub struct FitArgs {
    /// CSV table with a header line.
    #[arg(long)]
    pub input: PathBuf,
    /// Column of x.
    #[arg(long)]
    pub x: String,
    /// Column of y.
    #[arg(long)]
    pub y: String,
    /// Column of the sd of x (errors in both variables).
    #[arg(long)]
    pub sigma_x: Option<String>,
    /// Column of the sd of y (default: unit weights).
    #[arg(long)]
    pub sigma_y: Option<String>,
    /// Polynomial degree, 0..=10.
    #[arg(long, default_value_t = 1)]
    pub degree: usize,
}

/// Fits a polynomial to the columns of a CSV table (docs/formats.md section 7).
pub fn fit_csv(args: &FitArgs) -> Result<fit::FitOutput, Error> {
    let path = args.input.as_path();
    let (sigma_x, sigma_y) = (args.sigma_x.as_deref(), args.sigma_y.as_deref());
    let wanted = [
        Some(args.x.as_str()),
        Some(args.y.as_str()),
        sigma_x,
        sigma_y,
    ];
    let (data, line_of_row) = read_columns(path, wanted)?;
    let degree = args.degree;
    let [xs, ys, sx, sy] = data;
    fit::fit(
        &xs,
        &ys,
        sigma_x.map(|_| sx.as_slice()),
        sigma_y.map(|_| sy.as_slice()),
        degree,
    )
    .map_err(|e| match e {
        fit::FitError::BadValue { row, message } => Error::Fit {
            path: path.to_path_buf(),
            line: Some(line_of_row.get(row - 1).copied().unwrap_or(row)),
            message,
        },
        e => Error::Fit {
            path: path.to_path_buf(),
            line: None,
            message: e.to_string(),
        },
    })
}

/// A CSV field as written: trimmed, and without the double quotes a spreadsheet puts around
/// it (a comma inside quotes is not read as one field: the tables fitted hold numbers).
fn field(f: &str) -> &str {
    let f = f.trim();
    f.strip_prefix('"')
        .and_then(|f| f.strip_suffix('"'))
        .map_or(f, str::trim)
}

/// The column of the header `names` called `name`; none, or two, is an error naming it.
fn column_index(path: &Path, names: &[&str], name: &str) -> Result<usize, Error> {
    let bad = |message: String| Error::Fit {
        path: path.to_path_buf(),
        line: None,
        message,
    };
    let mut at = names.iter().enumerate().filter(|(_, n)| **n == name);
    let (first, _) = at.next().ok_or_else(|| {
        bad(format!(
            "no column `{name}` (columns: {})",
            names.join(", ")
        ))
    })?;
    if let Some((second, _)) = at.next() {
        return Err(bad(format!(
            "two columns are named `{name}` (columns {} and {}): which one is meant?",
            first + 1,
            second + 1
        )));
    }
    Ok(first)
}

/// The columns `wanted` (x, y and the optional sigmas, by name) of the CSV table at `path`,
/// and the file's line of each data row: blank lines and `#` comments skipped, a
/// byte-order mark dropped, every error naming the file, the line and the column.
#[allow(
    clippy::type_complexity,
    reason = "four columns and their rows' lines, once"
)]
fn read_columns(
    path: &Path,
    wanted: [Option<&str>; 4],
) -> Result<([Vec<f64>; 4], Vec<usize>), Error> {
    if path.is_dir() {
        return Err(Error::Fit {
            path: path.to_path_buf(),
            line: None,
            message: "is a folder, not a CSV file".to_owned(),
        });
    }
    let text =
        std::fs::read_to_string(path).map_err(|e| ingest::Error::io(path.to_path_buf(), e))?;
    // A byte-order mark (spreadsheets write one) is not part of the first column's name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (_, header) = lines.next().ok_or_else(|| Error::Fit {
        path: path.to_path_buf(),
        line: None,
        message: "no header line".to_owned(),
    })?;
    let names: Vec<&str> = header.split(',').map(field).collect();
    let cols: Vec<Option<usize>> = wanted
        .iter()
        .map(|w| w.map(|name| column_index(path, &names, name)).transpose())
        .collect::<Result<_, _>>()?;
    let mut data: [Vec<f64>; 4] = Default::default();
    // The file's line of each data row, for messages about a row.
    let mut line_of_row = Vec::new();
    for (n, line) in lines {
        line_of_row.push(n + 1);
        let fields: Vec<&str> = line.split(',').map(field).collect();
        for (k, c) in cols.iter().enumerate() {
            if let Some(c) = c {
                let bad = |message: String| Error::Fit {
                    path: path.to_path_buf(),
                    line: Some(n + 1),
                    message: format!("{}: {message}", names[*c]),
                };
                let f = fields.get(*c).ok_or_else(|| {
                    bad(format!(
                        "missing (the line has {} field(s), the header {})",
                        fields.len(),
                        names.len()
                    ))
                })?;
                let v = f
                    .parse::<f64>()
                    .map_err(|_| bad(format!("`{f}` is not a number")))?;
                data[k].push(v);
            }
        }
    }
    Ok((data, line_of_row))
}
