//! A long step's progress as one log line, for output that is not a
//! terminal (the trainer's features and epochs, the generator's renders).

/// A long step's progress as one log line, for output that is not a
/// terminal: "features: 120/744 (16 %), 0:45 elapsed, about 3:54 left;
/// MESSAGE", the time left extrapolated from the rate so far.
pub fn progress_line(
    prefix: &str,
    pos: u64,
    len: u64,
    elapsed: std::time::Duration,
    message: &str,
) -> String {
    let pct = (pos * 100).checked_div(len).unwrap_or(100);
    let left = match pos {
        0 => "time left unknown".to_string(),
        _ if pos >= len => "done".to_string(),
        _ => {
            let secs = elapsed.as_secs_f64() * (len - pos) as f64 / pos as f64;
            format!(
                "about {} left",
                clock(std::time::Duration::from_secs_f64(secs))
            )
        }
    };
    let mut line = format!(
        "{prefix}: {pos}/{len} ({pct} %), {} elapsed, {left}",
        clock(elapsed)
    );
    if !message.is_empty() {
        line += "; ";
        line += message;
    }
    line
}

/// H:MM:SS, or M:SS under an hour.
fn clock(d: std::time::Duration) -> String {
    let s = d.as_secs();
    match s / 3600 {
        0 => format!("{}:{:02}", s / 60, s % 60),
        h => format!("{h}:{:02}:{:02}", (s % 3600) / 60, s % 60),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_line_gives_counts_and_extrapolates_the_time_left() {
        let line = progress_line("features", 120, 480, Duration::from_secs(45), "0 cached");
        assert_eq!(
            line,
            "features: 120/480 (25 %), 0:45 elapsed, about 2:15 left; 0 cached"
        );
        let start = progress_line("epoch 1", 0, 10, Duration::ZERO, "");
        assert_eq!(
            start,
            "epoch 1: 0/10 (0 %), 0:00 elapsed, time left unknown"
        );
        let end = progress_line("predict", 10, 10, Duration::from_secs(3725), "");
        assert_eq!(end, "predict: 10/10 (100 %), 1:02:05 elapsed, done");
        assert!(progress_line("x", 0, 0, Duration::ZERO, "").contains("0/0 (100 %)"));
    }
}
