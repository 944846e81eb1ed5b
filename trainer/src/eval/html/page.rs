//! `report.html`: one evaluation, every table of `report.md`, the charts,
//! and every video as a strip of frames with each run's answers.

use super::frames::{FrameMark, FrameRecord};
use super::svg::{time_chart, Line};
use super::{esc, pct, pct_ms};
use crate::eval::metrics::{scalars, HandDecision, VideoOutcome};
use crate::eval::Report;
use grasp_policy::OutcomeKind;
use grasp_schema::taxonomy::{Class, Preshape};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

/// Frames shown per video at most; longer videos show every k-th scored
/// frame (the vote and the hand's decision still read them all).
pub const MAX_COLUMNS: usize = 48;

/// The page, and the number of thumbnails drawn.
pub fn report_page(report: &Report) -> (String, usize) {
    let title = format!(
        "Evaluation: {} ({}, {} run(s))",
        report
            .dataset
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| report.dataset.display().to_string()),
        report.head,
        report.runs.len()
    );
    let mut s = super::head(&title);
    let _ = writeln!(s, "<body>\n<header class=\"top\"><h1>{}</h1>", esc(&title));
    facts(&mut s, report);
    s.push_str(
        "<nav><a href=\"#accuracy\">accuracy</a> <a href=\"#hand\">the hand's decision</a> \
         <a href=\"#time\">over time</a> <a href=\"#confusion\">confusion</a> \
         <a href=\"#parts\">per part</a> <a href=\"#baseline\">baseline</a> \
         <a href=\"#videos\">videos</a></nav>\n</header>\n<main>\n",
    );
    accuracy(&mut s, report);
    hand(&mut s, report);
    time(&mut s, report);
    confusion(&mut s, report);
    parts(&mut s, report);
    baseline(&mut s, report);
    let thumbnails = videos(&mut s, report);
    s.push_str("</main>\n");
    s.push_str(&super::tail(include_str!("assets/report.js")));
    (s, thumbnails)
}

/// What was evaluated, how, and what was left out.
fn facts(s: &mut String, r: &Report) {
    let mut items = vec![
        format!(
            "<b>Mode: {}</b> (head: {}{})",
            esc(&r.mode),
            esc(&r.head),
            if r.backbone.is_empty() {
                String::new()
            } else {
                format!("; {}", esc(&r.backbone))
            }
        ),
        format!(
            "Dataset: <code>{}</code>",
            esc(&r.dataset.display().to_string())
        ),
        format!(
            "Videos: {} per run; runs (seeds): {}",
            r.runs.first().map(|x| x.metrics.videos).unwrap_or(0),
            r.runs.len()
        ),
    ];
    if !r.pooled_with.is_empty() {
        let roots: Vec<String> = r
            .pooled_with
            .iter()
            .map(|p| format!("<code>{}</code>", esc(&p.display().to_string())))
            .collect();
        items.push(format!("<b>Pooled</b> with {}", roots.join(", ")));
    }
    if !r.window.is_all() {
        items.push(format!(
            "<b>Frames scored: {}</b> ({} video(s) with no frame in the window left out)",
            esc(&r.window.describe()),
            r.videos_outside_window
        ));
    }
    if let Some(input) = &r.input {
        items.push(format!("Checkpoints' {}", esc(&input.describe())));
    }
    if let Some(t) = r.lead_in_trimmed.filter(|t| t.frames > 0) {
        items.push(format!(
            "Lead-in trimmed before inference: {} frame(s) of {} video(s)",
            t.frames, t.videos
        ));
    }
    if let Some(n) = r.train_sequences {
        let cap = r
            .sequences_per_pair
            .map(|k| format!(" (at most {k} per object-part pair)"))
            .unwrap_or_default();
        items.push(format!("Training set: {n} sequences{cap}"));
    }
    if let Some(b) = &r.bad_data {
        items.push(format!(
            "<b>Bad data skipped: {} problem(s)</b>, listed in <code>{}</code>",
            b.skipped,
            esc(&b.listed_in.display().to_string())
        ));
    }
    s.push_str("<ul class=\"facts\">\n");
    for i in items {
        let _ = writeln!(s, "<li>{i}</li>");
    }
    s.push_str("</ul>\n");
}

/// A headline scalar's name in words (unknown names as they are).
fn metric_label(key: &str) -> &str {
    match key {
        "video_accuracy" => "per-video (majority vote, no_grasp excluded)",
        "video_accuracy_single" => "per-video, single-grasp objects",
        "video_accuracy_multi" => "per-video, multi-grasp objects",
        "frame_accuracy" => "per-frame, with no_grasp",
        "frame_accuracy_without_no_grasp" => "per-frame, without no_grasp frames",
        "baseline_video_accuracy" => "baseline: perfect object classifier",
        "hand_accuracy" => "the hand's decision (hannes-run's policy)",
        "hand_accuracy_single" => "the hand's decision, single-grasp objects",
        "hand_accuracy_multi" => "the hand's decision, multi-grasp objects",
        "last_second_accuracy" => "per-frame, the last second before contact",
        other => other,
    }
}

fn accuracy(s: &mut String, r: &Report) {
    let _ = writeln!(
        s,
        "<section id=\"accuracy\"><h2>Accuracy (%), mean ± std over {} run(s)</h2>",
        r.runs.len()
    );
    let Some(first) = r.runs.first() else {
        s.push_str("<p>No runs.</p></section>\n");
        return;
    };
    s.push_str("<table class=\"num\"><thead><tr><th>metric</th><th>mean ± std</th>");
    for run in &r.runs {
        let _ = write!(
            s,
            "<th title=\"{}\">seed {}</th>",
            esc(&run.checkpoint.display().to_string()),
            run.seed
        );
    }
    s.push_str("</tr></thead><tbody>\n");
    let per_run: Vec<_> = r.runs.iter().map(|run| scalars(&run.metrics)).collect();
    for (i, (key, _)) in scalars(&first.metrics).into_iter().enumerate() {
        let class = if key.starts_with("hand") {
            " class=\"hand\""
        } else if key.starts_with("baseline") {
            " class=\"baseline\""
        } else {
            ""
        };
        let _ = write!(
            s,
            "<tr{class}><td>{}</td><td>{}</td>",
            esc(metric_label(key)),
            pct_ms(r.aggregate.get(key))
        );
        for v in &per_run {
            let _ = write!(s, "<td>{}</td>", pct(v.get(i).and_then(|x| x.1)));
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody></table>\n<p class=\"note\">Rules as in report.md: a frame's prediction is the argmax; a video's is the majority vote over frames predicted as a pre-shape; the hand's decision is what hannes-run's policy commands on the video's frames (a fallback counts by the pre-shape it sends, no command or an abort as wrong).</p>\n</section>\n");
}

fn hand(s: &mut String, r: &Report) {
    s.push_str(
        "<section id=\"hand\"><h2>The hand's decision: how it was taken, videos per run</h2>\n",
    );
    if let Some(p) = &r.policy {
        let _ = writeln!(
            s,
            "<p class=\"note\">Policy: window {} s, early margin {}, at least {} votes, \
             winner's share ≥ {}, mean confidence ≥ {}, fallback {}, decisions older than {} ms \
             never sent.</p>",
            p.window_s,
            p.early_margin
                .map(|m| m.to_string())
                .unwrap_or_else(|| "none".into()),
            p.min_votes,
            p.min_share,
            p.min_confidence,
            p.fallback.map(|f| f.name()).unwrap_or("none"),
            p.max_decision_age_ms
        );
    }
    s.push_str("<table class=\"num\"><thead><tr><th>seed</th>");
    for k in OutcomeKind::ALL {
        let _ = write!(s, "<th>{}</th>", k.name());
    }
    s.push_str("<th>right (%)</th><th>mean decision time (s)</th></tr></thead><tbody>\n");
    for run in &r.runs {
        let h = &run.metrics.hand;
        let _ = write!(s, "<tr><td>{}</td>", run.seed);
        for k in OutcomeKind::ALL {
            let _ = write!(s, "<td>{}</td>", h.outcomes.get(&k).copied().unwrap_or(0));
        }
        let _ = writeln!(
            s,
            "<td>{}</td><td>{}</td></tr>",
            pct(Some(h.accuracy)),
            h.mean_decision_s
                .map(|t| format!("{t:.2}"))
                .unwrap_or_else(|| "–".into())
        );
    }
    s.push_str("</tbody></table>\n</section>\n");
}

fn time(s: &mut String, r: &Report) {
    s.push_str(
        "<section id=\"time\"><h2>Accuracy against time (Fig. 5), pre-shape frames, summed over runs</h2>\n",
    );
    let lines = [
        Line {
            name: "single-grasp",
            class: "l-single",
            values: r.time_single.accuracy(),
        },
        Line {
            name: "multi-grasp",
            class: "l-multi",
            values: r.time_multi.accuracy(),
        },
        Line {
            name: "no_grasp, single",
            class: "l-ng-single",
            values: r.time_single.no_grasp_share(),
        },
        Line {
            name: "no_grasp, multi",
            class: "l-ng-multi",
            values: r.time_multi.no_grasp_share(),
        },
    ];
    s.push_str(&time_chart(&lines, r.time_bin_s));
    s.push_str(
        "<p class=\"note\">Share of the frames labelled with a pre-shape whose prediction is it \
         (solid: multi-grasp objects, dashed: single-grasp), and the share answered no_grasp \
         (grey: an abstention, not a wrong part), in bins of ",
    );
    let _ = writeln!(s, "{} s since each video's first frame.</p>", r.time_bin_s);
    s.push_str("</section>\n");
}

fn confusion(s: &mut String, r: &Report) {
    s.push_str("<section id=\"confusion\"><h2>Confusion (rows: truth; summed over runs)</h2>\n<div class=\"pair\">\n");
    let classes = Class::names();
    let pre: Vec<&str> = Preshape::ALL.iter().map(|p| p.name()).collect();
    matrix(
        s,
        "frames (columns: prediction)",
        &r.frame_confusion,
        &classes,
    );
    matrix(s, "videos (columns: vote)", &r.video_confusion, &pre);
    s.push_str("</div>\n</section>\n");
}

fn matrix(s: &mut String, caption: &str, m: &[Vec<u64>], names: &[&str]) {
    let _ = write!(
        s,
        "<table class=\"confusion\"><caption>{}</caption><thead><tr><th></th>",
        esc(caption)
    );
    for n in names {
        let _ = write!(s, "<th>{}</th>", esc(n));
    }
    s.push_str("</tr></thead><tbody>\n");
    for (i, (name, row)) in names.iter().zip(m).enumerate() {
        let total: u64 = row.iter().sum();
        let _ = write!(s, "<tr><th>{}</th>", esc(name));
        for (j, v) in row.iter().enumerate() {
            let share = if total > 0 {
                *v as f64 / total as f64
            } else {
                0.0
            };
            let fg = if share > 0.55 { "#fff" } else { "#111" };
            let diag = if i == j { " class=\"diag\"" } else { "" };
            let _ = write!(
                s,
                "<td{diag} style=\"background:rgba(33,102,172,{share:.2});color:{fg}\" \
                 title=\"{:.1} % of the row\">{v}</td>",
                share * 100.0
            );
        }
        s.push_str("</tr>\n");
    }
    s.push_str("</tbody></table>\n");
}

fn parts(s: &mut String, r: &Report) {
    s.push_str("<section id=\"parts\"><h2>Per-part accuracy of multi-grasp objects (%), mean ± std over runs</h2>\n");
    if r.per_part.is_empty() {
        s.push_str("<p>No multi-grasp object with recorded parts in this data.</p></section>\n");
        return;
    }
    s.push_str("<table class=\"num\"><thead><tr><th>object</th><th>part</th><th>pre-shape</th><th>videos</th><th>per-video</th><th>per-frame (pre-shape frames)</th></tr></thead><tbody>\n");
    for p in &r.per_part {
        let _ = writeln!(
            s,
            "<tr><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&p.object),
            esc(&p.part),
            p.preshape.name(),
            p.videos,
            pct_ms(Some(&p.video_accuracy)),
            pct_ms(p.frame_accuracy.as_ref())
        );
    }
    s.push_str("</tbody></table>\n</section>\n");
}

fn baseline(s: &mut String, r: &Report) {
    s.push_str("<section id=\"baseline\"><h2>Baseline: the perfect object classifier's answer per object</h2>\n");
    if let Some(first) = r.runs.first() {
        s.push_str("<table class=\"compact\"><thead><tr><th>object</th><th>pre-shape</th></tr></thead><tbody>\n");
        for (o, p) in &first.metrics.baseline.object_preshape {
            let _ = writeln!(s, "<tr><td>{}</td><td>{}</td></tr>", esc(o), p.name());
        }
        s.push_str("</tbody></table>\n");
    }
    s.push_str("</section>\n");
}

/// A class's short name on a frame's mark.
fn short(c: Class) -> &'static str {
    match c {
        Class::Power => "pow",
        Class::Lateral => "lat",
        Class::Pinch => "pin",
        Class::Pinch3 => "p3",
        Class::NoGrasp => "ng",
    }
}

/// One video over the runs.
struct Row<'a> {
    id: &'a str,
    first: &'a VideoOutcome,
    /// Per run its outcome (None where the run did not score the video).
    outcomes: Vec<Option<&'a VideoOutcome>>,
    vote_wrong: usize,
    hand_wrong: usize,
}

fn hand_right(o: &VideoOutcome) -> Option<bool> {
    o.hand.as_ref().map(|h| h.is_right(o.truth))
}

/// The videos section; returns the thumbnails drawn.
fn videos(s: &mut String, r: &Report) -> usize {
    let by_run: Vec<BTreeMap<&str, &VideoOutcome>> = r
        .runs
        .iter()
        .map(|run| run.videos.iter().map(|v| (v.id.as_str(), v)).collect())
        .collect();
    let mut rows: Vec<Row> = Vec::new();
    let mut seen = BTreeSet::new();
    for v in r.runs.iter().flat_map(|run| &run.videos) {
        if !seen.insert(v.id.as_str()) {
            continue;
        }
        let outcomes: Vec<Option<&VideoOutcome>> = by_run
            .iter()
            .map(|m| m.get(v.id.as_str()).copied())
            .collect();
        let present = outcomes.iter().flatten();
        let vote_wrong = present.clone().filter(|o| o.vote != o.truth).count();
        let hand_wrong = present.filter(|o| hand_right(o) == Some(false)).count();
        rows.push(Row {
            id: &v.id,
            first: v,
            outcomes,
            vote_wrong,
            hand_wrong,
        });
    }
    // The wrong videos first: by wrong votes, then wrong hand decisions.
    rows.sort_by(|a, b| {
        (b.vote_wrong + b.hand_wrong, b.vote_wrong)
            .cmp(&(a.vote_wrong + a.hand_wrong, a.vote_wrong))
            .then(a.id.cmp(b.id))
    });
    let wrong = rows.iter().filter(|r| r.vote_wrong > 0).count();
    let _ = writeln!(
        s,
        "<section id=\"videos\"><h2>Videos ({}, {} with a wrong vote in some run), the wrong ones first</h2>",
        rows.len(),
        wrong
    );
    filters(s, &rows);
    legend(s, r.frames.as_deref());
    let strips: Vec<Option<(super::strips::Strip, Vec<usize>)>> = match r.frames.as_deref() {
        Some(rec) => rows
            .par_iter()
            .map(|row| {
                let seq = rec.sequence(row.id)?;
                let cols = shown_columns(&rec.columns(row.id));
                Some((super::strips::strip(seq, &cols), cols))
            })
            .collect(),
        None => rows.iter().map(|_| None).collect(),
    };
    let mut thumbnails = 0;
    s.push_str("<div id=\"video-list\">\n");
    for (row, strip) in rows.iter().zip(&strips) {
        thumbnails += strip.as_ref().map_or(0, |(_, c)| c.len());
        video(s, r, row, strip.as_ref());
    }
    s.push_str("</div>\n</section>\n");
    thumbnails
}

/// At most [`MAX_COLUMNS`] of `cols`: every k-th, and the last.
fn shown_columns(cols: &[usize]) -> Vec<usize> {
    if cols.len() <= MAX_COLUMNS {
        return cols.to_vec();
    }
    let k = cols.len().div_ceil(MAX_COLUMNS - 1);
    let mut out: Vec<usize> = cols.iter().step_by(k).copied().collect();
    if out.last() != cols.last() {
        out.extend(cols.last());
    }
    out
}

fn filters(s: &mut String, rows: &[Row]) {
    let objects: BTreeSet<&str> = rows.iter().map(|r| r.first.object.as_str()).collect();
    let parts: BTreeSet<&str> = rows
        .iter()
        .filter_map(|r| r.first.part.as_deref())
        .collect();
    let truths: BTreeSet<Preshape> = rows.iter().map(|r| r.first.truth).collect();
    let select = |s: &mut String, id: &str, label: &str, all: &str, values: Vec<&str>| {
        let _ = write!(
            s,
            "<label>{label} <select id=\"f-{id}\"><option value=\"\">{all}</option>"
        );
        for v in values {
            let _ = write!(s, "<option value=\"{0}\">{0}</option>", esc(v));
        }
        s.push_str("</select></label>\n");
    };
    s.push_str("<form class=\"filters\" onsubmit=\"return false\">\n");
    select(
        s,
        "object",
        "object",
        "every object",
        objects.into_iter().collect(),
    );
    select(s, "part", "part", "every part", parts.into_iter().collect());
    let names: Vec<&str> = truths.iter().map(|p| p.name()).collect();
    select(s, "truth", "pre-shape", "every pre-shape", names);
    s.push_str(
        "<label>outcome <select id=\"f-outcome\"><option value=\"\">right and wrong</option>\
         <option value=\"vote-wrong\">vote wrong (some run)</option>\
         <option value=\"vote-right\">vote right (every run)</option>\
         <option value=\"hand-wrong\">hand wrong (some run)</option>\
         <option value=\"hand-right\">hand right (every run)</option></select></label>\n\
         <span id=\"f-count\" class=\"count\"></span>\n</form>\n",
    );
}

fn legend(s: &mut String, rec: Option<&FrameRecord>) {
    if rec.is_none() {
        s.push_str("<p class=\"note\">This report carries no frames (written from report.json, not by <code>grasp-train eval</code>): votes and decisions only.</p>\n");
        return;
    }
    s.push_str(
        "<p class=\"legend\">Each frame: the square the model saw outlined in yellow (the rest \
         dimmed); under it the frame's label, then per run the predicted class and its \
         probability (%): <span class=\"m ok\">right</span> <span class=\"m bad\">wrong</span> \
         <span class=\"m ng\">no_grasp on a pre-shape frame</span>; at the row's end the run's \
         vote and the hand's decision. Classes: pow = power, lat = lateral, pin = pinch, \
         p3 = pinch3, ng = no_grasp. Hover a mark for its time.</p>\n",
    );
}

fn verdict(right: bool) -> &'static str {
    if right {
        "ok"
    } else {
        "bad"
    }
}

fn hand_text(h: &HandDecision) -> String {
    let what = h.preshape.map(|p| p.name()).unwrap_or("none");
    let at = h.at_s.map(|t| format!(" at {t:.1} s")).unwrap_or_default();
    format!("{what} ({}{at})", h.how.name())
}

fn video(
    s: &mut String,
    r: &Report,
    row: &Row,
    strip: Option<&(super::strips::Strip, Vec<usize>)>,
) {
    let v = row.first;
    let part = v.part.as_deref().unwrap_or("");
    let _ = writeln!(
        s,
        "<article class=\"video\" data-object=\"{}\" data-part=\"{}\" data-truth=\"{}\" \
         data-vote-wrong=\"{}\" data-hand-wrong=\"{}\" data-id=\"{}\">",
        esc(&v.object),
        esc(part),
        v.truth.name(),
        row.vote_wrong,
        row.hand_wrong,
        esc(row.id)
    );
    let _ = writeln!(
        s,
        "<h3><span class=\"obj\">{}</span>{} · truth <span class=\"tag truth\">{}</span> \
         <span class=\"vid\">{}</span></h3>",
        esc(&v.object),
        if part.is_empty() {
            String::new()
        } else {
            format!(" / <span class=\"part\">{}</span>", esc(part))
        },
        v.truth.name(),
        esc(row.id)
    );
    let rec = r.frames.as_deref();
    let n = strip.map_or(0, |(_, c)| c.len());
    let (tw, th) = strip.map_or((0, 0), |(st, _)| (st.thumb_w, st.thumb_h));
    let columns = if n == 0 {
        "4.5em auto".to_string()
    } else {
        format!("4.5em repeat({n}, {tw}px) auto")
    };
    let _ = writeln!(
        s,
        "<div class=\"strip\" style=\"grid-template-columns: {columns}\">"
    );
    if let Some((st, cols)) = strip {
        let mut crop = match st.crop {
            Some(f) => format!("the model saw the centre {f:.2} of the shorter side"),
            None => "the model saw the whole frame".into(),
        };
        if let Some(r) = st.rendered {
            crop += &format!("; shown: the rendered centre ({r:.2} of the frame, black around)");
        }
        let unreadable = match st.unreadable {
            0 => String::new(),
            k => format!("{k} unreadable (grey)"),
        };
        let _ = writeln!(
            s,
            "<div class=\"rl\"></div><img class=\"frames\" style=\"grid-column: 2 / span {n}\" \
             width=\"{}\" height=\"{th}\" alt=\"{} frames of {}\" title=\"{crop}\" src=\"{}\">\
             <div class=\"dh\">{unreadable}</div>",
            tw as usize * n,
            n,
            esc(row.id),
            st.uri
        );
        // The frames' labels, from any run that scored each.
        let labels: BTreeMap<usize, &FrameMark> = (0..rec.map_or(0, FrameRecord::runs))
            .flat_map(|k| rec.map_or(&[][..], |x| x.marks(k, row.id)).iter())
            .map(|m| (m.frame, m))
            .collect();
        s.push_str("<div class=\"rl\">label</div>");
        for c in cols {
            match labels.get(c) {
                Some(m) => {
                    let class = if m.label == Class::NoGrasp {
                        "t ng"
                    } else {
                        "t"
                    };
                    let _ = write!(
                        s,
                        "<span class=\"{class}\" title=\"frame {c}, {:.2} s: label {}\">{}</span>",
                        m.time_s,
                        m.label.name(),
                        short(m.label)
                    );
                }
                None => s.push_str("<span class=\"t\"></span>"),
            }
        }
        s.push_str("<span class=\"dh\">vote · hand</span>\n");
    } else {
        s.push_str("<div class=\"rl\"></div><span class=\"dh\">vote · hand</span>\n");
    }
    for (k, (run, outcome)) in r.runs.iter().zip(&row.outcomes).enumerate() {
        let _ = write!(s, "<div class=\"rl\">seed {}</div>", run.seed);
        if let Some((_, cols)) = strip {
            let marks: BTreeMap<usize, &FrameMark> = rec
                .map_or(&[][..], |x| x.marks(k, row.id))
                .iter()
                .map(|m| (m.frame, m))
                .collect();
            for c in cols {
                match marks.get(c) {
                    Some(m) => {
                        let class = if m.class == m.label {
                            "ok"
                        } else if m.class == Class::NoGrasp {
                            "ng"
                        } else {
                            "bad"
                        };
                        let _ = write!(
                            s,
                            "<span class=\"m {class}\" title=\"{:.2} s: {} {:.0} %\">{} {:.0}</span>",
                            m.time_s,
                            m.class.name(),
                            m.confidence * 100.0,
                            short(m.class),
                            m.confidence * 100.0
                        );
                    }
                    None => s.push_str("<span class=\"m none\"></span>"),
                }
            }
        }
        match outcome {
            Some(o) => {
                let hand = match &o.hand {
                    Some(h) => format!(
                        " · <span class=\"tag {}\" title=\"{}\">hand: {}</span>",
                        verdict(h.is_right(o.truth)),
                        esc(h.why.as_deref().unwrap_or(h.how.name())),
                        esc(&hand_text(h))
                    ),
                    None => String::new(),
                };
                let _ = writeln!(
                    s,
                    "<span class=\"dec\"><span class=\"tag {}\">vote: {}</span>{hand}</span>",
                    verdict(o.vote == o.truth),
                    o.vote.name()
                );
            }
            None => s.push_str("<span class=\"dec\">not scored</span>\n"),
        }
    }
    s.push_str("</div>\n</article>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_videos_show_every_kth_frame_and_the_last() {
        let cols: Vec<usize> = (0..150).collect();
        let shown = shown_columns(&cols);
        assert!(shown.len() <= MAX_COLUMNS, "{}", shown.len());
        assert_eq!(shown[0], 0);
        assert_eq!(*shown.last().unwrap(), 149);
        let few: Vec<usize> = (3..20).collect();
        assert_eq!(shown_columns(&few), few);
    }
}
