//! `cargo xtask check <dataset>`: the manifest validated, and the head and tail of every log
//! read by ingest's own readers, printing per file what a full ingest will read (layout,
//! time form, first and last time, rate, channels) or the error naming file, line and field.
//!
//! How: a scratch copy of the dataset in which every log keeps its first and last
//! [`PEEK_BYTES`] and loses its middle (a text log's middle lines become empty lines, so
//! every line keeps its number; a binary log's middle becomes a hole of zero bytes, so every
//! byte keeps its offset), ingested by `ingest::run_with` into a scratch OUT. The readers,
//! the time gate, the plausibility checks and the session checks are the ones a full run
//! uses; what the copy's middle adds (blank lines, zero bytes skipped) is taken off again.

use anyhow::{Context, Result};
use ingest::contract::ingest_ledger::{FileLedger, IngestReport};
use ingest::contract::manifest::{Acquisition, Dataset, ResolvedSession};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Bytes read at each end of a log.
pub const PEEK_BYTES: u64 = 64 * 1024;

/// A log of the dataset: its path relative to the folder and what its middle became.
struct Peeked {
    rel: PathBuf,
    /// Lines (text) or bytes (binary) of the middle left out; 0 when read whole.
    left_out: u64,
    binary: bool,
    /// How the log writes its times.
    time_form: String,
}

/// Checks `dataset`; prints per file what will be read. Returns whether all is well.
pub fn run(dataset: &Path, w: &mut impl Write) -> Result<bool> {
    let ds = match Dataset::load(dataset) {
        Ok(ds) => ds,
        Err(e) => {
            writeln!(w, "check: {e}")?;
            return Ok(false);
        }
    };
    writeln!(
        w,
        "check: {} is valid: {} session(s), {} accelerometer(s)",
        ds.manifest_path.display(),
        ds.sessions.len(),
        ds.manifest.instrument.accelerometer.len()
    )?;
    let scratch = std::env::temp_dir().join(format!("gravcal-check-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    let copy = scratch.join("dataset");
    let result = peek_all(&ds, &copy, &scratch.join("out"), w);
    let _ = std::fs::remove_dir_all(&scratch);
    result
}

fn peek_all(ds: &Dataset, copy: &Path, out: &Path, w: &mut impl Write) -> Result<bool> {
    std::fs::create_dir_all(copy).with_context(|| format!("creating {}", copy.display()))?;
    std::fs::copy(&ds.manifest_path, copy.join("dataset.toml"))
        .with_context(|| format!("copying {}", ds.manifest_path.display()))?;
    let mut peeked = Vec::new();
    for s in &ds.sessions {
        for (path, binary, time_form) in logs(s) {
            let rel = path
                .strip_prefix(&ds.dir)
                .map(Path::to_path_buf)
                .unwrap_or_else(|_| path.clone());
            // A log outside the dataset is read where it is (the copied manifest names it
            // there); only what lies inside is trimmed into the scratch copy.
            let left_out = match in_copy(copy, &ds.dir, &path) {
                Some(to) => trim(&path, &to, binary)?,
                None => 0,
            };
            peeked.push(Peeked {
                rel,
                left_out,
                binary,
                time_form,
            });
        }
        // The trajectory is not ingest's: copied whole, for the manifest to validate.
        if let Some(src) = &s.trajectory {
            let attitude = src.attitude.as_ref().map(|(p, _)| p);
            for path in std::iter::once(&src.path).chain(attitude) {
                let Some(to) = in_copy(copy, &ds.dir, path) else {
                    continue;
                };
                if let Some(dir) = to.parent() {
                    std::fs::create_dir_all(dir)
                        .with_context(|| format!("creating {}", dir.display()))?;
                }
                std::fs::copy(path, &to).with_context(|| format!("copying {}", path.display()))?;
            }
        }
    }
    let opts = ingest::Options {
        skip_bad_lines: false,
        progress: false,
    };
    let outcome = ingest::run_with(copy, out, &opts);
    let ledger = IngestReport::load(&out.join("ingest"));
    let dataset_dir = ds.dir.display().to_string();
    let scratch_dir = copy.display().to_string();
    let scratch_out = out.display().to_string();
    // The scratch folders are gone when the user reads this: the dataset's own files are
    // named, and the ingest's output folder as a run's (OUT).
    let real = |s: String| {
        s.replace(&scratch_dir, &dataset_dir)
            .replace(&scratch_out, "OUT")
    };
    if let Ok(report) = &ledger {
        let spans = Spans::read(&out.join("ingest"), ds).unwrap_or_default();
        for f in &report.files {
            let p = peeked.iter().find(|p| p.rel == Path::new(&f.path));
            print_file(f, p, report, &spans, w)?;
        }
    }
    let mut tracks_read = true;
    for s in &ds.sessions {
        tracks_read &= print_trajectory(ds, s, w)?;
    }
    match outcome {
        Ok(_) if !tracks_read => Ok(false),
        Ok(_) => {
            writeln!(
                w,
                "check: every log reads; a full run reads the parts left out here too"
            )?;
            Ok(true)
        }
        Err(e) => {
            writeln!(w, "check: {}", real(e.to_string()))?;
            Ok(false)
        }
    }
}

/// A survey session's trajectory and attitude read whole with the gravity stage's readers:
/// their epochs, first and last time and rate, or the error naming file, line and field.
/// Returns whether they read.
fn print_trajectory(ds: &Dataset, s: &ResolvedSession, w: &mut impl Write) -> Result<bool> {
    use adjust::survey::gravity::trajectory::{read_csv, read_dgs_laptop, read_nmea, read_rtklib};
    use ingest::contract::survey::TrajectoryFormat;
    let Some(src) = &s.trajectory else {
        return Ok(true);
    };
    let rel = src
        .path
        .strip_prefix(&ds.dir)
        .unwrap_or(&src.path)
        .display()
        .to_string();
    let (layout, read) = match src.format {
        TrajectoryFormat::Rtklib => ("RTKLIB solution", read_rtklib(&src.path, false)),
        TrajectoryFormat::DgsLaptop => (
            "DGS laptop file, no heights: at the sea surface",
            read_dgs_laptop(&src.path, false),
        ),
        TrajectoryFormat::Csv => {
            let form = src.time.unwrap_or(ingest::base::time::TimeForm::Iso);
            ("CSV", read_csv(&src.path, s.times.reader(form), false))
        }
        TrajectoryFormat::Nmea => (
            match adjust::survey::gravity::trajectory::nmea_scan(&src.path) {
                Ok(scan) if scan.gga => match scan.heights {
                    ingest::contract::survey::Heights::Ellipsoidal => {
                        "NMEA, GGA fixes, heights above the ellipsoid (altitude plus separation)"
                    }
                    ingest::contract::survey::Heights::SeaLevel => {
                        "NMEA, GGA fixes, heights above sea level (a GGA without the geoid's \
                         separation)"
                    }
                },
                _ => "NMEA, RMC fixes, no heights: at the sea surface",
            },
            read_nmea(&src.path, s.date, false),
        ),
    };
    let t = match read {
        Ok(t) => t,
        Err(e) => {
            writeln!(w, "{rel} (session {}, trajectory): {e}", s.session.id)?;
            return Ok(false);
        }
    };
    let what = format!("(session {}, trajectory; {layout})", s.session.id);
    print_epochs(&rel, &what, &t.time_gps_ns, w)?;
    let Some((path, form)) = &src.attitude else {
        return Ok(true);
    };
    let rel = path
        .strip_prefix(&ds.dir)
        .unwrap_or(path)
        .display()
        .to_string();
    let read = adjust::survey::gravity::attitude::read_csv(
        path,
        s.times.reader(*form),
        s.gps_range_ns(),
        false,
    );
    match read {
        Ok(a) => {
            let what = format!("(session {}, attitude; CSV)", s.session.id);
            print_epochs(&rel, &what, &a.time_gps_ns, w)?;
            for (why, n) in &a.dropped {
                writeln!(w, "  {n} sample(s) dropped by the time gate: {why}")?;
            }
            Ok(true)
        }
        Err(e) => {
            writeln!(w, "{rel} (session {}, attitude): {e}", s.session.id)?;
            Ok(false)
        }
    }
}

/// A file of epochs read whole: how many, the first and last, the median rate.
fn print_epochs(rel: &str, what: &str, times: &[i64], w: &mut impl Write) -> Result<()> {
    let n = times.len();
    let mut d: Vec<i64> = times.windows(2).map(|x| x[1] - x[0]).collect();
    d.sort_unstable();
    let rate = d
        .get(d.len() / 2)
        .filter(|&&m| m > 0)
        .map_or("-".to_owned(), |&m| format!("{:.4} Hz", 1e9 / m as f64));
    let span = times
        .first()
        .zip(times.last())
        .map_or(String::new(), |(a, b)| {
            format!(
                ", first {} last {}",
                ingest::base::time::utc_iso(*a),
                ingest::base::time::utc_iso(*b)
            )
        });
    writeln!(w, "{rel} {what}: read whole; {n} epochs{span}, {rate}")?;
    Ok(())
}

/// Every log of a session: its path, whether it is a binary log, how it writes its times.
fn logs(s: &ResolvedSession) -> Vec<(PathBuf, bool, String)> {
    let t = &s.times;
    let text = |p: &PathBuf, form: ingest::base::time::TimeForm| {
        let scale = if form == ingest::base::time::TimeForm::Iso {
            format!(" (zone-less times in {})", scale_name(t.scale))
        } else {
            String::new()
        };
        (p.clone(), false, format!("times {}{scale}", form.name()))
    };
    let mut out = match &s.acquisition {
        Acquisition::Binary(p) => vec![(
            p.clone(),
            true,
            "binary frames, GPS time (10-bit week + tow)".to_owned(),
        )],
        Acquisition::Csv { adc, temperature } => {
            let mut v = vec![text(adc, t.adc)];
            v.extend(temperature.iter().map(|p| text(p, t.temperature)));
            v
        }
        Acquisition::Lab {
            stream,
            temperature,
            ..
        } => {
            let mut v = vec![text(stream, t.adc)];
            v.extend(temperature.iter().map(|p| text(p, t.temperature)));
            v
        }
    };
    out.extend(s.theodolite.iter().map(|p| text(p, t.theodolite)));
    out
}

/// Where a log at `path` goes in the scratch copy `copy` of the dataset `dir`: the same
/// place relative to it, in any subfolder; None for a path outside the dataset (or leading
/// out of it by `..`), which is never copied onto (a copy of a file onto itself empties it).
fn in_copy(copy: &Path, dir: &Path, path: &Path) -> Option<PathBuf> {
    let rel = path.strip_prefix(dir).ok()?;
    rel.components()
        .all(|c| matches!(c, std::path::Component::Normal(_)))
        .then(|| copy.join(rel))
}

/// Writes `to`: `from` with its middle left out as the module says; returns the lines
/// (text) or bytes (binary) left out.
pub(crate) fn trim(from: &Path, to: &Path, binary: bool) -> Result<u64> {
    use std::io::Read;
    if let Some(dir) = to.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut src =
        std::fs::File::open(from).with_context(|| format!("reading {}", from.display()))?;
    let n = src.metadata()?.len();
    if n <= 2 * PEEK_BYTES {
        std::fs::copy(from, to).with_context(|| format!("writing {}", to.display()))?;
        return Ok(0);
    }
    // The ends only, and the middle streamed when its lines must be counted: memory stays
    // at the two ends and a buffer, whatever the log's size.
    let read_at = |src: &mut std::fs::File, at: u64, len: u64| -> std::io::Result<Vec<u8>> {
        src.seek(SeekFrom::Start(at))?;
        let mut v = Vec::new();
        src.take(len).read_to_end(&mut v)?;
        Ok(v)
    };
    let mut f = std::fs::File::create(to).with_context(|| format!("writing {}", to.display()))?;
    if binary {
        // Cut at frame boundaries of a log that starts with a frame.
        let frame = ingest::readers::gcb::FRAME_LEN as u64;
        let head = PEEK_BYTES - PEEK_BYTES % frame;
        let tail = n - PEEK_BYTES - (n - PEEK_BYTES) % frame;
        f.write_all(&read_at(&mut src, 0, head)?)?;
        f.seek(SeekFrom::Start(tail))?;
        f.write_all(&read_at(&mut src, tail, n - tail)?)?;
        return Ok(tail - head);
    }
    // Cut after a line break at each end; the middle's lines become empty lines.
    let head = read_at(&mut src, 0, PEEK_BYTES)?;
    let head_end = head.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1) as u64;
    let tail = read_at(&mut src, n - PEEK_BYTES, PEEK_BYTES)?;
    let tail_start = tail
        .iter()
        .position(|&b| b == b'\n')
        .map_or(n, |i| n - PEEK_BYTES + i as u64 + 1);
    let mut lines = 0u64;
    src.seek(SeekFrom::Start(head_end))?;
    let mut middle = (&mut src).take(tail_start - head_end);
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let k = middle.read(&mut buf)?;
        if k == 0 {
            break;
        }
        lines += buf[..k].iter().filter(|&&b| b == b'\n').count() as u64;
    }
    f.write_all(&head[..head_end as usize])?;
    f.write_all(&vec![b'\n'; lines as usize])?;
    f.write_all(&tail[(tail_start - (n - PEEK_BYTES)) as usize..])?;
    Ok(lines)
}

/// A few lines about one file: what was read of it, accepted and rejected, and the
/// session's times and rate.
fn print_file(
    f: &FileLedger,
    p: Option<&Peeked>,
    report: &IngestReport,
    spans: &Spans,
    w: &mut impl Write,
) -> Result<()> {
    let left_out = p.map_or(0, |p| p.left_out);
    let binary = p.is_some_and(|p| p.binary);
    let what = match (binary, left_out) {
        (_, 0) => "read whole".to_owned(),
        (true, n) => format!("first and last {PEEK_BYTES} bytes read ({n} left out)"),
        (false, n) => format!("head and tail read ({n} lines left out)"),
    };
    // The binary copy's hole of zero bytes, skipped while resynchronising, is not the log's.
    let hole = |at: &str| binary && left_out > 0 && at == format!("byte {}", hole_start());
    writeln!(
        w,
        "{} (session {}, {}; {}): {what}; {}",
        f.path,
        f.session,
        f.role,
        p.map_or("", |p| p.time_form.as_str()),
        f.counts_line()
    )?;
    // An empty stream has no separator or header to speak of.
    let lines = f.read + f.comment_blank_or_header_lines.unwrap_or(0);
    if let Some(lab) = f.lab_stream.as_ref().filter(|_| lines > 0) {
        writeln!(
            w,
            "  lab stream: {}-separated, {}header{}",
            if lab.comma_separated {
                "comma"
            } else {
                "space"
            },
            if lab.header { "" } else { "no " },
            lab.stamp_step_ns
                .map(|s| format!(", stamps every {:.6} s", s as f64 * 1e-9))
                .unwrap_or_default()
        )?;
    }
    for r in f.rejections.iter().filter(|r| !hole(&r.at)).take(3) {
        writeln!(w, "  {} {}: {}", r.at, r.reason, r.detail)?;
    }
    let time = |t: i64| ingest::base::time::utc_iso(t);
    for (what, span) in spans.of(&f.session, &f.role) {
        writeln!(
            w,
            "  {what}: {} accepted, first {}, last {} (of what was read)",
            span.2,
            time(span.0),
            time(span.1)
        )?;
    }
    if let Some(s) = report.sessions.iter().find(|s| s.id == f.session)
        && matches!(f.role.as_str(), "acquisition" | "adc_csv")
    {
        writeln!(
            w,
            "  rate: {} measured{}",
            s.measured_sample_rate_hz
                .map_or("none".to_owned(), |r| format!("{r:.4} Hz")),
            if s.channels_never_connected.is_empty() {
                String::new()
            } else {
                format!(
                    "; channels never connected: {:?}",
                    s.channels_never_connected
                )
            }
        )?;
    }
    Ok(())
}

/// First and last time (GPS, ns) and count of what each table holds, by session id and
/// stream.
#[derive(Default)]
struct Spans(std::collections::BTreeMap<(String, &'static str), (i64, i64, u64)>);

impl Spans {
    fn add(&mut self, session: &str, stream: &'static str, t: i64) {
        let e = self
            .0
            .entry((session.to_owned(), stream))
            .or_insert((t, t, 0));
        e.0 = e.0.min(t);
        e.1 = e.1.max(t);
        e.2 += 1;
    }

    /// The tables of OUT/ingest (`dir`).
    fn read(dir: &Path, ds: &Dataset) -> Result<Self> {
        let ids: Vec<&str> = ds.sessions.iter().map(|s| s.session.id.as_str()).collect();
        let id = |i: u16| ids.get(usize::from(i)).copied().unwrap_or("?");
        let mut spans = Spans::default();
        ingest::contract::tables::acceleration::for_each(dir, |s, t, _, _| {
            spans.add(id(s), "acceleration", t)
        })?;
        ingest::contract::tables::lab::batches(dir, 1 << 16, |b| {
            for (&s, &t) in b.session.iter().zip(b.time_ns) {
                spans.add(id(s), "lab readings", t);
            }
            Ok::<(), ingest::Error>(())
        })?;
        for ((s, _), (times, _)) in ingest::contract::tables::temperature::read(dir)? {
            // Every channel's series has the same times: count one channel's.
            if spans.0.contains_key(&(id(s).to_owned(), "temperature")) {
                continue;
            }
            for &t in &times {
                spans.add(id(s), "temperature", t);
            }
        }
        for (session, rows) in ingest::contract::tables::theodolite::read(dir)? {
            for r in rows {
                spans.add(&session, "readings", r.time_gps_ns);
            }
        }
        Ok(spans)
    }

    /// What a file of `role` in `session` gave.
    fn of(&self, session: &str, role: &str) -> Vec<(&'static str, (i64, i64, u64))> {
        let streams: &[&'static str] = match role {
            "acquisition" => &["acceleration", "temperature"],
            "adc_csv" => &["acceleration", "lab readings"],
            "temperature_csv" => &["temperature"],
            "theodolite" => &["readings"],
            _ => &[],
        };
        streams
            .iter()
            .filter_map(|&k| Some((k, *self.0.get(&(session.to_owned(), k))?)))
            .collect()
    }
}

/// Where the binary copy's hole starts: the head's end, cut at a frame boundary.
fn hole_start() -> u64 {
    let frame = ingest::readers::gcb::FRAME_LEN as u64;
    PEEK_BYTES - PEEK_BYTES % frame
}

fn scale_name(s: ingest::contract::manifest::TimeScale) -> &'static str {
    use ingest::contract::manifest::TimeScale;
    match s {
        TimeScale::Utc => "UTC",
        TimeScale::Gpst => "GPST",
        TimeScale::Tai => "TAI",
    }
}
