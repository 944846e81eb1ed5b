//! `index.html` beside a summary (`grasp-train summarize`): the summary's
//! tables with a link to each report's `report.html`, the shipped model and
//! why, and, when given, the dataset preview and the phases' times
//! (`scripts/main.sh` passes `OUT/preview/contact_sheet.png` and
//! `OUT/timing.json`).

use super::{esc, pct_ms};
use crate::error::SummaryError;
use crate::eval::summary::{Row, Summary};
use std::fmt::Write;
use std::path::{Component, Path, PathBuf};

/// What the index shows besides the summary.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IndexExtras {
    /// A picture of the dataset (`grasp-gen preview`'s contact sheet),
    /// embedded when the file exists.
    pub preview: Option<PathBuf>,
    /// A JSON object of phase names to seconds (`scripts/main.sh`'s
    /// `timing.json`), shown when the file exists.
    pub timing: Option<PathBuf>,
}

/// Pictures larger than this are linked instead of embedded.
const EMBED_MAX_BYTES: u64 = 8 << 20;

/// Writes `dir/index.html`.
pub fn write_index(
    summary: &Summary,
    dir: &Path,
    extras: &IndexExtras,
) -> Result<(), SummaryError> {
    let html = index_page(summary, dir, extras);
    Ok(grasp_support::atomic::write_atomic(
        &dir.join("index.html"),
        html.as_bytes(),
    )?)
}

/// The page for a summary written into `dir`.
pub fn index_page(summary: &Summary, dir: &Path, extras: &IndexExtras) -> String {
    let title = summary
        .spec
        .title
        .clone()
        .unwrap_or_else(|| "Summary of evaluations".into());
    let mut s = super::head(&title);
    let _ = writeln!(s, "<body>\n<header class=\"top\"><h1>{}</h1>", esc(&title));
    s.push_str(
        "<p class=\"note\">Per-video accuracy (%), mean ± std (population) over each report's \
         runs (seeds). Each cell links to its report.html: every video's frames with each \
         run's answers. Also: <a href=\"summary.md\">summary.md</a>, \
         <a href=\"summary.json\">summary.json</a>.</p>\n</header>\n<main>\n",
    );
    if let Some(choice) = &summary.choice {
        shipped(&mut s, choice);
    }
    if summary.spec.by_condition {
        condition_table(&mut s, summary, dir);
    }
    every_report(&mut s, summary, dir);
    parts(&mut s, summary);
    if let Some(t) = &extras.timing {
        timing(&mut s, t, dir);
    }
    if let Some(p) = &extras.preview {
        preview(&mut s, p, dir);
    }
    s.push_str("</main>\n");
    s.push_str(&super::tail(""));
    s
}

fn shipped(s: &mut String, choice: &crate::eval::choice::Choice) {
    let _ = writeln!(
        s,
        "<section id=\"shipped\"><h2>The shipped model: <code>{}</code></h2>\n\
         <p>Chosen by its <b>worst</b> test set: a model tuned on its own conditions can \
         lose most where it was never tuned (another renderer, real meshes, another reach), \
         so each model is ranked by its lowest accuracy of the hand's decision (what \
         hannes-run's policy commands) over every test set (mean over seeds; ties by the worst \
         per-video vote, then the mean over the sets). Only a head that classifies frame by \
         frame (FC) can ship: the hand's loop (hannes-run) runs nothing else.</p>",
        esc(&choice.shipped)
    );
    s.push_str(
        "<table class=\"num\"><thead><tr><th>model</th><th>head</th><th>worst test set \
         (the hand)</th><th>the hand's decision there</th><th>worst per-video vote</th>\
         <th>mean of the hand's decision</th><th></th></tr></thead><tbody>\n",
    );
    for st in &choice.standings {
        let (class, mark) = if st.model == choice.shipped {
            (" class=\"shipped\"", "shipped".to_string())
        } else if !st.runs_on_hand() {
            (
                "",
                format!(
                    "not shippable: its {} head does not run on the hand",
                    st.head
                ),
            )
        } else {
            ("", String::new())
        };
        let _ = writeln!(
            s,
            "<tr{class}><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:.1}</td><td>{:.1} ({})</td><td>{:.1}</td><td class=\"l\">{}</td></tr>",
            esc(&st.model),
            esc(&st.head),
            esc(&st.worst_set),
            st.worst_hand_accuracy * 100.0,
            st.worst_vote_accuracy * 100.0,
            esc(&st.worst_vote_set),
            st.mean_hand_accuracy * 100.0,
            esc(&mark)
        );
    }
    s.push_str("</tbody></table>\n</section>\n");
}

/// The link from `dir` to a row's report.html, and whether it exists.
fn report_link(row: &Row, dir: &Path) -> (String, bool) {
    let page = row.source.with_file_name("report.html");
    (href(dir, &page), page.is_file())
}

/// A cell linking `text` to the row's report.html (plain when the page
/// is not there: a report written before report.html existed).
fn linked(text: &str, row: &Row, dir: &Path) -> String {
    match report_link(row, dir) {
        (link, true) => format!("<a href=\"{}\">{}</a>", esc(&link), esc(text)),
        (_, false) => format!("{} <span class=\"note\">(no report.html)</span>", esc(text)),
    }
}

fn condition_table(s: &mut String, summary: &Summary, dir: &Path) {
    let conditions = summary.conditions();
    s.push_str("<section id=\"conditions\"><h2>Per-video accuracy by test set</h2>\n<table class=\"num\"><thead><tr><th>model</th>");
    for c in &conditions {
        let _ = write!(s, "<th>{}</th>", esc(c));
    }
    s.push_str("</tr></thead><tbody>\n");
    for m in summary.models() {
        let shipped = summary.choice.as_ref().is_some_and(|c| c.shipped == m);
        let class = if shipped { " class=\"shipped\"" } else { "" };
        let _ = write!(s, "<tr{class}><td>{}</td>", esc(&m));
        for c in &conditions {
            match summary.rows.iter().find(|r| r.group_name() == (&m, c)) {
                Some(row) => {
                    let cell = pct_ms(Some(&row.video_accuracy));
                    let _ = write!(s, "<td>{}</td>", linked(&cell, row, dir));
                }
                None => s.push_str("<td>–</td>"),
            }
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody></table>\n</section>\n");
}

fn every_report(s: &mut String, summary: &Summary, dir: &Path) {
    let x = summary.has_x();
    s.push_str("<section id=\"reports\"><h2>Every report</h2>\n<table class=\"num\"><thead><tr><th>report</th>");
    if x {
        let _ = write!(s, "<th>{}</th>", esc(summary.x_label()));
    }
    s.push_str(
        "<th>runs</th><th>per-video</th><th>the hand's decision</th><th>per-frame</th>\
         <th>per-frame w/o no_grasp</th><th>last second before contact</th><th>baseline</th>\
         <th>single-grasp videos</th><th>multi-grasp videos</th>\
         <th>head</th><th>test data</th><th>frames scored</th></tr></thead><tbody>\n",
    );
    for r in &summary.rows {
        let wrong = match report_link(r, dir) {
            (link, true) => format!(
                " <a class=\"note\" href=\"{}#outcome=vote-wrong\">wrong videos</a>",
                esc(&link)
            ),
            _ => String::new(),
        };
        let _ = write!(s, "<tr><td>{}{wrong}</td>", linked(&r.label, r, dir));
        if x {
            let xv = r.x.map(|v| v.to_string()).unwrap_or_else(|| "–".into());
            let _ = write!(s, "<td>{xv}</td>");
        }
        let _ = writeln!(
            s,
            "<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td class=\"l\">{}</td><td class=\"l\"><code>{}</code></td><td class=\"l\">{}</td></tr>",
            r.runs,
            pct_ms(Some(&r.video_accuracy)),
            pct_ms(r.hand_accuracy.as_ref()),
            pct_ms(r.frame_accuracy.as_ref()),
            pct_ms(r.frame_accuracy_without_no_grasp.as_ref()),
            pct_ms(r.last_second_accuracy.as_ref()),
            pct_ms(r.baseline_video_accuracy.as_ref()),
            pct_ms(r.video_accuracy_single.as_ref()),
            pct_ms(r.video_accuracy_multi.as_ref()),
            esc(&r.head),
            esc(&r.dataset.display().to_string()),
            esc(&r.window.describe())
        );
    }
    s.push_str("</tbody></table>\n</section>\n");
}

/// Per-video accuracy of each part of the multi-grasp objects: one row per
/// part (and model, by condition), the reports or conditions as columns.
fn parts(s: &mut String, summary: &Summary) {
    let parts = summary.parts();
    if parts.is_empty() {
        return;
    }
    let cell = |row: Option<&Row>, object: &str, part: &str| {
        let p = row.and_then(|r| {
            r.per_part
                .iter()
                .find(|p| p.object == object && p.part == part)
        });
        pct_ms(p.map(|p| &p.video_accuracy))
    };
    s.push_str("<section id=\"parts\"><h2>Per-part per-video accuracy of multi-grasp objects</h2>\n<table class=\"num\"><thead><tr>");
    if summary.spec.by_condition {
        let conditions = summary.conditions();
        s.push_str("<th>model</th><th>object</th><th>part</th><th>pre-shape</th>");
        for c in &conditions {
            let _ = write!(s, "<th>{}</th>", esc(c));
        }
        s.push_str("</tr></thead><tbody>\n");
        for m in summary.models() {
            for (object, part, preshape) in &parts {
                let _ = write!(
                    s,
                    "<tr><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td>",
                    esc(&m),
                    esc(object),
                    esc(part),
                    esc(preshape)
                );
                for c in &conditions {
                    let row = summary.rows.iter().find(|r| r.group_name() == (&m, c));
                    let _ = write!(s, "<td>{}</td>", cell(row, object, part));
                }
                s.push_str("</tr>\n");
            }
        }
    } else {
        s.push_str("<th>object</th><th>part</th><th>pre-shape</th>");
        for r in &summary.rows {
            let _ = write!(s, "<th>{}</th>", esc(&r.label));
        }
        s.push_str("</tr></thead><tbody>\n");
        for (object, part, preshape) in &parts {
            let _ = write!(
                s,
                "<tr><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td>",
                esc(object),
                esc(part),
                esc(preshape)
            );
            for r in &summary.rows {
                let _ = write!(s, "<td>{}</td>", cell(Some(r), object, part));
            }
            s.push_str("</tr>\n");
        }
    }
    s.push_str("</tbody></table>\n</section>\n");
}

fn timing(s: &mut String, file: &Path, dir: &Path) {
    s.push_str("<section id=\"timing\"><h2>Time per phase</h2>\n");
    let parsed = std::fs::read_to_string(file)
        .ok()
        .and_then(|t| serde_json::from_str::<Ordered>(&t).ok());
    let Some(Ordered(phases)) = parsed else {
        let _ = writeln!(
            s,
            "<p class=\"note\">No timing yet (<code>{}</code> is absent or not a JSON object).</p></section>",
            esc(&href(dir, file))
        );
        return;
    };
    s.push_str("<table class=\"num\"><thead><tr><th>phase</th><th>seconds</th><th>minutes</th></tr></thead><tbody>\n");
    for (name, v) in &phases {
        let name = name.as_str();
        match v.as_f64() {
            Some(sec) => {
                let _ = writeln!(
                    s,
                    "<tr><td>{}</td><td>{sec:.0}</td><td>{:.1}</td></tr>",
                    esc(name),
                    sec / 60.0
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "<tr><td>{}</td><td colspan=\"2\">{}</td></tr>",
                    esc(name),
                    esc(&v.to_string())
                );
            }
        }
    }
    let _ = writeln!(
        s,
        "</tbody></table>\n<p class=\"note\">From <a href=\"{0}\">{0}</a>.</p>\n</section>",
        esc(&href(dir, file))
    );
}

/// A JSON object's entries in the file's order (the phases run in it).
struct Ordered(Vec<(String, serde_json::Value)>);

impl<'de> serde::Deserialize<'de> for Ordered {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Entries;
        impl<'de> serde::de::Visitor<'de> for Entries {
            type Value = Ordered;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut m: A,
            ) -> Result<Ordered, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = m.next_entry()? {
                    entries.push(entry);
                }
                Ok(Ordered(entries))
            }
        }
        d.deserialize_map(Entries)
    }
}

fn preview(s: &mut String, file: &Path, dir: &Path) {
    s.push_str("<section id=\"preview\"><h2>The training data</h2>\n");
    let link = esc(&href(dir, file));
    let small = std::fs::metadata(file).is_ok_and(|m| m.len() <= EMBED_MAX_BYTES);
    match std::fs::read(file) {
        Ok(bytes) if small => {
            let mime = match file.extension().and_then(|e| e.to_str()) {
                Some("jpg" | "jpeg") => "image/jpeg",
                Some("gif") => "image/gif",
                _ => "image/png",
            };
            let _ = writeln!(
                s,
                "<p class=\"note\">A sample of the frames (<a href=\"{link}\">{link}</a>).</p>\n\
                 <img class=\"preview\" alt=\"the dataset's contact sheet\" src=\"{}\">",
                super::data_uri(mime, &bytes)
            );
        }
        Ok(_) => {
            let _ = writeln!(
                s,
                "<p><a href=\"{link}\">{link}</a> (too large to embed)</p>"
            );
        }
        Err(_) => {
            let _ = writeln!(
                s,
                "<p class=\"note\">No preview (<code>{link}</code> is absent).</p>"
            );
        }
    }
    s.push_str("</section>\n");
}

/// The relative URL from directory `from` to `to` (both taken from the
/// current directory when relative), with `/` separators and unsafe
/// characters percent-encoded.
pub fn href(from: &Path, to: &Path) -> String {
    let abs = |p: &Path| normalize(&std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()));
    let (from, to) = (abs(from), abs(to));
    let a: Vec<Component> = from.components().collect();
    let b: Vec<Component> = to.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = vec!["..".into(); a.len() - common];
    parts.extend(
        b[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts
        .iter()
        .map(|p| percent_encode(p))
        .collect::<Vec<_>>()
        .join("/")
}

/// `p` without `.` and with `..` applied lexically.
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

fn percent_encode(segment: &str) -> String {
    let mut s = String::new();
    for b in segment.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            s.push(b as char);
        } else {
            let _ = write!(s, "%{b:02X}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_are_relative_and_encoded() {
        let from = Path::new("/r/out/report");
        assert_eq!(
            href(from, Path::new("/r/out/report/fc/default/report.html")),
            "fc/default/report.html"
        );
        assert_eq!(
            href(from, Path::new("/r/out/preview/contact sheet.png")),
            "../preview/contact%20sheet.png"
        );
        assert_eq!(
            href(from, Path::new("/r/out/./report/../timing.json")),
            "../timing.json"
        );
    }
}
