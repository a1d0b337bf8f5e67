//! Self-contained HTML reports: text, tables and the SVG plots inlined (no network, no files
//! beside it needed to open it).

use miette::{miette, IntoDiagnostic, Result, WrapErr};
use physid_ident::RankedParam;
use std::fmt::Write as _;
use std::path::Path;

/// Parameters' units and one-line meanings, by name (the models' `PARAMS`, `UNITS` and
/// `DESCRIPTIONS`): every table of parameters carries them.
#[derive(Clone, Copy, Default)]
pub struct Glossary<'a> {
    /// The names.
    pub names: &'a [&'a str],
    /// Their units.
    pub units: &'a [&'a str],
    /// What each stands for.
    pub descriptions: &'a [&'a str],
}

impl Glossary<'_> {
    /// The unit and meaning of `name` ("—" and "" for a name it does not know: a user's formula
    /// parameter).
    pub fn of(&self, name: &str) -> (String, String) {
        match self.names.iter().position(|n| *n == name) {
            Some(j) => (
                self.units.get(j).copied().unwrap_or("—").to_string(),
                self.descriptions.get(j).copied().unwrap_or("").to_string(),
            ),
            None => ("—".into(), String::new()),
        }
    }
}

/// A report under construction.
pub struct Report {
    html: String,
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

impl Report {
    /// A report with a title and a one-line subtitle.
    pub fn new(title: &str, subtitle: &str) -> Self {
        let mut html = String::new();
        let _ = write!(
            html,
            "<!doctype html><html><head><meta charset=\"utf-8\"><title>{t}</title><style>\
body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222;line-height:1.45}}\
h1{{font-size:1.6em}}h2{{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}}\
table{{border-collapse:collapse;margin:.6em 0}}td,th{{border:1px solid #ccc;padding:.25em .6em;text-align:right}}\
th{{background:#f3f3f3}}td{{white-space:nowrap}}td.t{{white-space:normal}}td:first-child,th:first-child,td.t,th.t{{text-align:left}}.note{{color:#555;font-size:.92em}}\
.ok{{color:#0a7a3a;font-weight:bold}}.alarm{{color:#b00020;font-weight:bold}}svg{{max-width:100%;height:auto}}\
</style></head><body><h1>{t}</h1><p class=\"note\">{s}</p>",
            t = esc(title),
            s = esc(subtitle)
        );
        Self { html }
    }

    /// A section heading.
    pub fn section(&mut self, title: &str) {
        let _ = write!(self.html, "<h2>{}</h2>", esc(title));
    }

    /// A paragraph (plain text; `class` "ok", "alarm" or "note" to colour it).
    pub fn para(&mut self, text: &str, class: Option<&str>) {
        match class {
            Some(c) => {
                let _ = write!(self.html, "<p class=\"{c}\">{}</p>", esc(text));
            }
            None => {
                let _ = write!(self.html, "<p>{}</p>", esc(text));
            }
        }
    }

    /// A table.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        // Numbers line up on the right, words read from the left (a column's header as its
        // first cell).
        let number = |c: &str| {
            c.trim_start_matches(['+', '-', '−'])
                .starts_with(|ch: char| ch.is_ascii_digit())
                || c == "—"
        };
        self.html.push_str("<table><tr>");
        for (j, h) in header.iter().enumerate() {
            let text = rows
                .first()
                .and_then(|r| r.get(j))
                .is_some_and(|c| !number(c));
            let class = if text { " class=\"t\"" } else { "" };
            let _ = write!(self.html, "<th{class}>{}</th>", esc(h));
        }
        self.html.push_str("</tr>");
        for r in rows {
            self.html.push_str("<tr>");
            for c in r {
                if number(c) {
                    let _ = write!(self.html, "<td>{}</td>", esc(c));
                } else {
                    let _ = write!(self.html, "<td class=\"t\">{}</td>", esc(c));
                }
            }
            self.html.push_str("</tr>");
        }
        self.html.push_str("</table>");
    }

    /// Inline an SVG file written by the plot module.
    pub fn svg(&mut self, path: &Path) -> Result<()> {
        let svg = std::fs::read_to_string(path)
            .map_err(|e| miette!("reading {}: {e}", path.display()))?;
        let start = svg.find("<svg").unwrap_or(0);
        self.html.push_str(&svg[start..]);
        Ok(())
    }

    /// An identifiability ranking (thesis Tables 7.3, 8.1): the table of parameters in
    /// selection order and the residual profile, drawn into `svg`.
    pub fn ranking(
        &mut self,
        ranked: &[RankedParam],
        glossary: Glossary,
        title: &str,
        svg: &Path,
    ) -> Result<()> {
        self.table(
            &[
                "parameter",
                "unit",
                "meaning",
                "rank",
                "relative residual",
                "estimable",
            ],
            &ranked
                .iter()
                .map(|row| {
                    let (unit, meaning) = glossary.of(&row.param);
                    vec![
                        row.param.clone(),
                        unit,
                        meaning,
                        row.rank.to_string(),
                        format!("{:.2e}", row.relative_residual),
                        if row.estimable { "yes" } else { "—" }.into(),
                    ]
                })
                .collect::<Vec<_>>(),
        );
        crate::plot::residual_profile(svg, title, ranked)?;
        self.svg(svg)
    }

    /// Write `report.html` to `path`, its provenance last (crate::provenance).
    pub fn write(mut self, path: &Path) -> Result<()> {
        let p = crate::provenance::current();
        self.section("Provenance");
        let mut rows = vec![
            vec!["physid".to_string(), p.physid.to_string()],
            vec!["written".into(), p.date.clone()],
            vec!["command".into(), p.command.clone()],
        ];
        for f in &p.inputs {
            rows.push(vec![
                "input".into(),
                match (&f.sha256, f.bytes, &f.error) {
                    (Some(h), Some(b), _) => format!("{} ({b} bytes, SHA-256 {h})", f.path),
                    (_, _, Some(e)) => format!("{} (no checksum: {e})", f.path),
                    _ => f.path.clone(),
                },
            ]);
        }
        rows.push(vec![
            "--map".into(),
            if p.map.is_empty() {
                "none (the file's own column names)".into()
            } else {
                p.map.join(", ")
            },
        ]);
        // Names and values, both read from the left: no header row.
        self.html.push_str("<table>");
        for r in &rows {
            let _ = write!(
                self.html,
                "<tr><th class=\"t\">{}</th><td class=\"t\">{}</td></tr>",
                esc(&r[0]),
                esc(&r[1])
            );
        }
        self.html.push_str("</table>");
        self.html.push_str("</body></html>\n");
        std::fs::write(path, self.html).map_err(|e| miette!("writing {}: {e}", path.display()))
    }
}

/// Create an output directory (`--out DIR`), saying which on failure.
pub fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .into_diagnostic()
        .wrap_err_with(|| format!("creating {}", dir.display()))
}

/// A verb's report on the file `data` in `dir` (`--out DIR`): the directory created, the report
/// titled `title`, its body written by `body` (given the report and the directory for its
/// figures), finished with the JSON as `DIR/json_name` ([`finish`]).
pub fn write(
    dir: &Path,
    title: &str,
    data: &Path,
    json_name: &str,
    json: &impl serde::Serialize,
    body: impl FnOnce(&mut Report, &Path) -> Result<()>,
) -> Result<()> {
    create_dir(dir)?;
    let mut rep = Report::new(title, &format!("{}", data.display()));
    body(&mut rep, dir)?;
    finish(dir, rep, json_name, json)
}

/// Finish an output directory: `DIR/report.html` and the JSON as `DIR/json_name`.
pub fn finish(
    dir: &Path,
    report: Report,
    json_name: &str,
    json: &impl serde::Serialize,
) -> Result<()> {
    report.write(&dir.join("report.html"))?;
    let path = dir.join(json_name);
    let json = crate::provenance::with(json);
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&json).into_diagnostic()?,
    )
    .map_err(|e| miette!("writing {}: {e}", path.display()))
}
