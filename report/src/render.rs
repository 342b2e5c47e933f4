//! The report's two renderings from one set of sections: GitHub-flavoured Markdown and one
//! self-contained HTML page (inline CSS with a print stylesheet, inline SVG, no script).

use super::*;

/// A table, rendered to Markdown and HTML from the same cells.
#[derive(Clone, Debug, Default)]
pub struct Table {
    /// Column headings.
    pub header: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with the headings `spec` writes as its Markdown would: separated by ` | `.
    pub(crate) fn headed(spec: &str) -> Self {
        Table {
            header: spec.split(" | ").map(str::to_owned).collect(),
            rows: Vec::new(),
        }
    }

    /// A table with the headings `header`.
    pub(crate) fn new(header: &[&str]) -> Self {
        Table {
            header: header.iter().map(|s| (*s).to_owned()).collect(),
            rows: Vec::new(),
        }
    }

    /// GitHub-flavoured Markdown.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "| {} |\n|{}|\n",
            self.header.join(" | "),
            vec!["---"; self.header.len()].join("|")
        );
        for r in &self.rows {
            let _ = writeln!(s, "| {} |", r.join(" | "));
        }
        s
    }

    /// An HTML table.
    pub fn html(&self) -> String {
        let mut s = String::from("<table><thead><tr>");
        for h in &self.header {
            let _ = write!(s, "<th>{}</th>", esc(h));
        }
        s.push_str("</tr></thead><tbody>");
        for r in &self.rows {
            s.push_str("<tr>");
            for c in r {
                let _ = write!(s, "<td>{}</td>", esc(c));
            }
            s.push_str("</tr>");
        }
        s.push_str("</tbody></table>");
        s
    }
}

pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// One section of the report: a heading, paragraphs, tables and plots.
#[derive(Clone, Debug, Default)]
pub struct Section {
    /// Heading.
    pub title: String,
    /// Paragraphs (plain text).
    pub text: Vec<String>,
    /// Tables, each with a caption.
    pub tables: Vec<(String, Table)>,
    /// Plots: file name (without folder) and SVG.
    pub plots: Vec<(String, String)>,
    /// Tables shown on demand (HTML: a collapsible block; Markdown: in full), each with a
    /// caption, under the table of [`Section::tables`] whose index it gives.
    pub details: Vec<(usize, String, Table)>,
}

pub(crate) fn section(title: &str) -> Section {
    Section {
        title: title.to_owned(),
        ..Section::default()
    }
}

/// The report's heading: a survey report when it opens on a survey reduced to gravity
/// (a dataset with nothing to calibrate), a calibration report otherwise.
pub fn heading(name: &str, sections: &[Section]) -> String {
    match sections.first() {
        Some(s) if s.title == gravity::TITLE => format!("Survey report: {name}"),
        _ => format!("Calibration report: {name}"),
    }
}

/// The report as Markdown.
pub fn markdown(name: &str, sections: &[Section]) -> String {
    let mut s = format!("# {}\n", heading(name, sections));
    for sec in sections {
        let _ = write!(s, "\n## {}\n\n", sec.title);
        for t in &sec.text {
            let _ = write!(s, "{t}\n\n");
        }
        for (i, (caption, t)) in sec.tables.iter().enumerate() {
            let _ = write!(s, "**{caption}**\n\n{}\n", t.markdown());
            for (_, caption, t) in sec.details.iter().filter(|d| d.0 == i) {
                let _ = write!(s, "**{caption}**\n\n{}\n", t.markdown());
            }
        }
        for (file, _) in &sec.plots {
            let _ = writeln!(s, "![{file}](plots/{file})");
        }
    }
    s
}

pub(crate) const CSS: &str = "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:0.85em}th,td{border:1px solid #bbb;padding:3px 6px;text-align:right}\
th{background:#eef}td:first-child,th:first-child{text-align:left}h1{border-bottom:2px solid #446}\
.plots{display:flex;flex-wrap:wrap;gap:8px}.plots figure{margin:0}caption,.caption{font-weight:bold;text-align:left}\
code{background:#f3f3f6;padding:0 3px;border-radius:3px;font-size:0.95em}details{margin:0 0 1em}summary{cursor:pointer;color:#446}\
@page{size:A4;margin:14mm}\
@media print{body{max-width:none;margin:0;padding:0;font-size:9pt}table{font-size:8pt;page-break-inside:auto}\
tr,figure{page-break-inside:avoid}h2,h3,.caption{page-break-after:avoid}.plots svg{max-width:100%;height:auto}\
details{display:block}details>*{display:block}code{background:none}}";

/// Markdown's inline code (`...`) as HTML `<code>` in already escaped text; an unpaired
/// backtick stays as it is.
pub(crate) fn inline_code(escaped: &str) -> String {
    let parts: Vec<&str> = escaped.split('`').collect();
    if parts.len().is_multiple_of(2) {
        return escaped.to_owned();
    }
    let mut out = String::with_capacity(escaped.len() + 16);
    for (i, p) in parts.iter().enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{p}</code>");
        } else {
            out.push_str(p);
        }
    }
    out
}

/// A section's id in the page: its title's words in lower case joined by `-`
/// (`summary-the-calibrations`).
pub(crate) fn anchor(title: &str) -> String {
    title
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_ascii_lowercase)
        .collect::<Vec<_>>()
        .join("-")
}

/// The report as one self-contained HTML page.
pub fn html(name: &str, sections: &[Section]) -> String {
    let heading = esc(&heading(name, sections));
    let mut s = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{heading}</title><style>{CSS}</style></head><body>\n<h1>{heading}</h1>\n"
    );
    for sec in sections {
        let _ = writeln!(
            s,
            "<section id=\"{}\"><h2>{}</h2>",
            anchor(&sec.title),
            esc(&sec.title)
        );
        for t in &sec.text {
            let _ = writeln!(s, "<p>{}</p>", inline_code(&esc(t)));
        }
        for (i, (caption, t)) in sec.tables.iter().enumerate() {
            let _ = writeln!(
                s,
                "<div class=\"caption\">{}</div>{}",
                esc(caption),
                t.html()
            );
            for (_, caption, t) in sec.details.iter().filter(|d| d.0 == i) {
                let _ = writeln!(
                    s,
                    "<details><summary>{}</summary>{}</details>",
                    esc(caption),
                    t.html()
                );
            }
        }
        if !sec.plots.is_empty() {
            s.push_str("<div class=\"plots\">");
            for (file, svg) in &sec.plots {
                let body = svg.find("<svg").map_or(svg.as_str(), |i| &svg[i..]);
                let _ = write!(s, "<figure id=\"{}\">{body}</figure>", esc(file));
            }
            s.push_str("</div>\n");
        }
        s.push_str("</section>\n");
    }
    s.push_str("</body></html>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::Table;

    /// The headings a table is given in Markdown's form are the ones its Markdown writes.
    #[test]
    fn headings_given_as_markdown_are_written_as_given() {
        let t = Table::headed(
            "where (lat, lon) | difference / sigma | test: statistic in [2.5 %, 97.5 %]",
        );
        assert_eq!(t.header.len(), 3, "{:?}", t.header);
        assert_eq!(
            t.header,
            Table::new(&[
                "where (lat, lon)",
                "difference / sigma",
                "test: statistic in [2.5 %, 97.5 %]"
            ])
            .header
        );
        assert!(t.markdown().starts_with(
            "| where (lat, lon) | difference / sigma | test: statistic in [2.5 %, 97.5 %] |\n"
        ));
    }
}
