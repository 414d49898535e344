//! Frame ranges: `A`, `A:B` or `A:B:STEP`, in the stage's time codes, and
//! the frames a command runs over (the option, or the stage's range).
//!
//! A run covers at most [`MAX_FRAMES`] time codes. The count is computed and
//! checked before anything is allocated, so `--frames 1:12:1e-18` or an
//! `endTimeCode` of 1e19 fail at once with a message instead of exhausting
//! memory.

use crate::error::{readable, Error, Result};
use crate::usd_io::stage::StageMetadata;

/// Most time codes one bake or render covers: a two-hour feature at 24 fps
/// is 172,800 frames, so this fits a whole film with two samples per frame,
/// while the list of times itself stays at 4 MB. Longer ranges are split
/// into several runs (farm chunks), which is how they are baked anyway.
pub const MAX_FRAMES: usize = 500_000;

/// An inclusive range of time codes with a positive step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameRange {
    pub start: f64,
    pub end: f64,
    pub step: f64,
}

impl std::str::FromStr for FrameRange {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let parts: Vec<&str> = s.split(':').collect();
        let num = |p: &str| -> std::result::Result<f64, String> {
            let v: f64 = p
                .trim()
                .parse()
                .map_err(|_| format!("{p:?} is not a number (expected A, A:B or A:B:STEP)"))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("{p:?} is not a finite number"))
            }
        };
        let (start, end, step) = match parts.as_slice() {
            [a] => (num(a)?, num(a)?, 1.0),
            [a, b] => (num(a)?, num(b)?, 1.0),
            [a, b, c] => (num(a)?, num(b)?, num(c)?),
            _ => return Err(format!("{s:?} is not a frame range (expected A, A:B or A:B:STEP)")),
        };
        let range = FrameRange { start, end, step };
        range.count()?;
        Ok(range)
    }
}

impl FrameRange {
    /// How many time codes the range holds, or why it is not a usable range:
    /// non-finite bounds, a step that is not positive or too small to move
    /// the time codes at their magnitude, end before start, or more than
    /// [`MAX_FRAMES`] time codes.
    pub fn count(&self) -> std::result::Result<usize, String> {
        let FrameRange { start, end, step } = *self;
        if !(start.is_finite() && end.is_finite() && step.is_finite()) {
            return Err(format!(
                "{}:{}:{} is not a finite range",
                readable(start),
                readable(end),
                readable(step)
            ));
        }
        if step <= 0.0 {
            return Err(format!("step {} must be positive", readable(step)));
        }
        if end < start {
            return Err(format!("end {} is before start {}", readable(end), readable(start)));
        }
        let n = ((end - start) / step + 1e-9).floor() + 1.0;
        if !(n.is_finite() && n <= MAX_FRAMES as f64) {
            // Exact below 2^53, where every count is an integer f64.
            let count = if n < 9e15 { format!("{n}") } else { readable(n) };
            return Err(format!(
                "{}:{} with step {} is {count} time codes; painterly covers at most \
                 {MAX_FRAMES} per run (bake the range in parts, each with its own --frames A:B)",
                readable(start),
                readable(end),
                readable(step)
            ));
        }
        // Every time code `times` makes must differ from the previous one in
        // f64. Checked on the codes themselves: a step just above half the
        // spacing of f64 near the end passes `end + step != end` and still
        // rounds two codes to one (at most MAX_FRAMES additions).
        let n = n as usize;
        let mut previous = start;
        for k in 1..n {
            let t = self.time_at(k);
            if t <= previous {
                return Err(format!(
                    "step {} is too small to separate time codes near {}",
                    readable(step),
                    readable(t)
                ));
            }
            previous = t;
        }
        Ok(n)
    }

    /// The time codes of the range, start first; the end is included when the
    /// step lands on it (within 1e-9). Never more than [`MAX_FRAMES`]; call
    /// [`count`](Self::count) first to reject ranges that are too long.
    pub fn times(&self) -> Vec<f64> {
        let n = self.count().unwrap_or_else(|_| {
            let n = (self.end - self.start) / self.step;
            if n.is_finite() && n >= 0.0 {
                ((n + 1e-9).floor() + 1.0).min(MAX_FRAMES as f64) as usize
            } else {
                0
            }
        });
        (0..n).map(|k| self.time_at(k)).collect()
    }

    /// Time code `k` of the range: what `times` lists and `count` checks.
    fn time_at(&self, k: usize) -> f64 {
        self.start + k as f64 * self.step
    }

    /// Checks the range lies within the stage's authored [start, end].
    pub fn check_within(&self, stage_start: f64, stage_end: f64) -> Result<()> {
        if self.start < stage_start - 1e-9 || self.end > stage_end + 1e-9 {
            return Err(Error::msg(format!(
                "--frames {}:{} is outside the stage's time range {}:{} (startTimeCode:endTimeCode)",
                readable(self.start),
                readable(self.end),
                readable(stage_start),
                readable(stage_end)
            )));
        }
        Ok(())
    }
}

/// `--chunk N`, frames per chunk (bake and farm): a count of at least 1 (a
/// usage error otherwise).
pub fn positive_count(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        Err(e) if *e.kind() == std::num::IntErrorKind::PosOverflow => {
            Err(format!("{s:?} is too large (at most {})", usize::MAX))
        }
        _ => Err(format!("{s:?} is not a whole number of at least 1")),
    }
}

/// The frames to run over: `frames` when given (checked against the stage's
/// range when it has one), else the stage's startTimeCode..endTimeCode.
/// Stage metadata problems (non-finite values, start after end, a range too
/// long) are errors naming the field; a bad `frames` is a usage error.
pub fn resolve(meta: &StageMetadata, frames: Option<FrameRange>) -> Result<Vec<f64>> {
    meta.validate()?;
    if let Some(f) = frames {
        f.count().map_err(|m| Error::usage(format!("--frames: {m}")))?;
    }
    let range = match (meta.start_time_code, meta.end_time_code) {
        (Some(s), Some(e)) if s > e => {
            return Err(Error::msg(format!(
                "the stage's startTimeCode {s} is after its endTimeCode {e}"
            )))
        }
        (Some(s), Some(e)) => Some((s, e)),
        _ => None,
    };
    match (frames, range) {
        (Some(f), Some((s, e))) => {
            f.check_within(s, e)?;
            Ok(f.times())
        }
        (Some(f), None) => Ok(f.times()),
        (None, Some((s, e))) => {
            let r = FrameRange {
                start: s,
                end: e,
                step: 1.0,
            };
            r.count().map_err(|m| {
                Error::msg(format!(
                    "the stage's range (startTimeCode:endTimeCode) {m}; pass --frames A:B"
                ))
            })?;
            Ok(r.times())
        }
        (None, None) => Err(Error::msg(match (meta.start_time_code, meta.end_time_code) {
            (Some(_), None) => "the stage has a startTimeCode but no endTimeCode: pass --frames A:B",
            (None, Some(_)) => "the stage has an endTimeCode but no startTimeCode: pass --frames A:B",
            _ => "the stage has no startTimeCode/endTimeCode: pass --frames A:B",
        })),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(start: Option<f64>, end: Option<f64>) -> StageMetadata {
        StageMetadata {
            start_time_code: start,
            end_time_code: end,
            ..Default::default()
        }
    }

    #[test]
    fn a_chunk_is_a_whole_number_of_at_least_one() {
        assert_eq!(positive_count("1"), Ok(1));
        assert_eq!(positive_count("48"), Ok(48));
        for bad in ["0", "-1", "1.5", "", "x"] {
            assert_eq!(
                positive_count(bad),
                Err(format!("{bad:?} is not a whole number of at least 1"))
            );
        }
    }

    #[test]
    fn parses_forms_and_rejects_bad_ones() {
        let r: FrameRange = "1:10:3".parse().unwrap();
        assert_eq!(r.times(), vec![1.0, 4.0, 7.0, 10.0]);
        assert_eq!("5".parse::<FrameRange>().unwrap().times(), vec![5.0]);
        assert_eq!("1:2:0.5".parse::<FrameRange>().unwrap().times(), vec![1.0, 1.5, 2.0]);
        for bad in [
            "1:",
            "a:b",
            "5:1",
            "1:10:0",
            "1:2:3:4",
            "",
            "nan:3",
            "1:inf",
            "1:12:1e-18",
            "1:12:1e-9",
        ] {
            assert!(bad.parse::<FrameRange>().is_err(), "{bad}");
        }
        // Too small a step for the magnitude of the time codes.
        assert!("1e17:1e17:1".parse::<FrameRange>().is_ok());
        assert!("1e17:100000000000000016:1".parse::<FrameRange>().is_err());
    }

    #[test]
    fn each_refusal_says_why() {
        let why = |s: &str| s.parse::<FrameRange>().unwrap_err();
        // Parsing refuses a non-finite number itself; `count` (public, and
        // what every range is checked with) refuses any one non-finite
        // field, whatever the others.
        assert_eq!(why("1:inf"), "\"inf\" is not a finite number");
        let (inf, nan) = (f64::INFINITY, f64::NAN);
        for (start, end, step) in [
            (nan, 3.0, 1.0),
            (inf, 3.0, 1.0),
            (1.0, inf, 1.0),
            (1.0, -inf, 1.0),
            (0.0, 10.0, inf),
            (0.0, 10.0, nan),
        ] {
            let e = FrameRange { start, end, step }.count().unwrap_err();
            assert_eq!(e, format!("{start}:{end}:{step} is not a finite range"));
        }
        assert_eq!(why("1:12:0"), "step 0 must be positive");
        assert_eq!(why("1:12:-2"), "step -2 must be positive");
        assert_eq!(why("5:1"), "end 1 is before start 5");
        assert_eq!(
            why("1e17:100000000000000016:1"),
            "step 1 is too small to separate time codes near 1e17"
        );
        // The count is exact (500001 is over the limit, as 5.000e5 did not
        // show), and far bounds are short.
        assert!(why("1:500001").starts_with("1:500001 with step 1 is 500001 time codes;"));
        assert!(why("-1e308:1e308").starts_with("-1e308:1e308 with step 1 is inf time codes;"));
        assert_eq!(why("1e-300:1e-301"), "end 1e-301 is before start 1e-300");
        // Just below 2^57 f64 is spaced 16 apart: a step of 10 moves `end`
        // (10 > 16/2) yet rounds 2^57 − 64 + 10 and + 20 both to 2^57 − 48.
        let (start, end) = (2f64.powi(57) - 64.0, 2f64.powi(57) - 16.0);
        let e = FrameRange { start, end, step: 10.0 }.count().unwrap_err();
        assert_eq!(
            e,
            format!("step 10 is too small to separate time codes near {:e}", start + 16.0)
        );
        let r = FrameRange { start, end, step: 16.0 };
        assert_eq!(r.count(), Ok(4));
        assert_eq!(r.times(), [64.0, 48.0, 32.0, 16.0].map(|d| 2f64.powi(57) - d));
    }

    #[test]
    fn frame_limit_is_exact() {
        let max = MAX_FRAMES as f64;
        let r: FrameRange = format!("1:{max}").parse().unwrap();
        assert_eq!(r.count(), Ok(MAX_FRAMES));
        assert!(format!("1:{}", max + 1.0).parse::<FrameRange>().is_err());
        assert!("0:1:0.00001".parse::<FrameRange>().is_ok());
        assert!("0:10:0.00001".parse::<FrameRange>().is_err());
    }

    #[test]
    fn resolves_against_the_stage() {
        assert_eq!(resolve(&meta(Some(1.0), Some(3.0)), None).unwrap(), vec![1.0, 2.0, 3.0]);
        let e = resolve(&meta(Some(5.0), Some(1.0)), None).unwrap_err();
        assert!(e.message.contains("after its endTimeCode"), "{e}");
        let e = resolve(&meta(Some(1.0), Some(1e19)), None).unwrap_err();
        assert!(e.message.contains("at most 500000"), "{e}");
        assert_eq!(e.exit_code(), 1);
        let e = resolve(&meta(Some(1.0), Some(f64::INFINITY)), None).unwrap_err();
        assert!(e.message.contains("endTimeCode") && e.message.contains("inf"), "{e}");
        let e = resolve(&meta(Some(f64::NAN), Some(3.0)), None).unwrap_err();
        assert!(e.message.contains("startTimeCode"), "{e}");
        let e = resolve(&meta(Some(1.0), None), None).unwrap_err();
        assert!(e.message.contains("no endTimeCode"), "{e}");
        let f = FrameRange {
            start: 1.0,
            end: 12.0,
            step: 1e-19,
        };
        assert_eq!(resolve(&meta(None, None), Some(f)).unwrap_err().exit_code(), 2);
        assert_eq!(f.times().len(), MAX_FRAMES);
    }

    // `FrameRange::times` on ranges that `count` refuses: its documented
    // fallback still lists `start + k·step` up to the end (within 1e-9), never
    // more than MAX_FRAMES codes, and nothing for a range that runs backwards
    // or does not move.

    fn range(start: f64, end: f64, step: f64) -> FrameRange {
        FrameRange { start, end, step }
    }

    #[test]
    fn a_range_whose_codes_collide_still_lists_every_step() {
        // Near 2^53 the f64 spacing is 2, so start + 1 and start + 3 round
        // (half to even) onto their neighbours: count refuses the range, and
        // times lists k = 0..=4 as IEEE rounds them.
        let start = 2f64.powi(53);
        let r = range(start, start + 4.0, 1.0);
        assert!(r.count().unwrap_err().contains("too small to separate"));
        let offsets: Vec<f64> = r.times().iter().map(|t| t - start).collect();
        assert_eq!(offsets, [0.0, 0.0, 2.0, 4.0, 4.0]);
    }

    #[test]
    fn backward_and_still_ranges_have_no_codes_and_a_long_one_is_cut() {
        let back = range(10.0, 2.0, 1.0);
        assert!(back.count().is_err());
        assert!(back.times().is_empty());
        // A step of zero never reaches the end: no codes, not MAX_FRAMES copies
        // of the start.
        let still = range(0.0, 5.0, 0.0);
        assert!(still.count().is_err());
        assert!(still.times().is_empty());
        let long = range(0.0, 2.0 * MAX_FRAMES as f64, 1.0);
        assert!(long.count().is_err());
        let t = long.times();
        assert_eq!(
            (t.len(), t[0], t[MAX_FRAMES - 1]),
            (MAX_FRAMES, 0.0, (MAX_FRAMES - 1) as f64)
        );
    }

    #[test]
    fn the_stage_range_check_allows_rounding_and_nothing_more() {
        assert!(range(1.0 - 1e-12, 10.0 + 1e-12, 1.0).check_within(1.0, 10.0).is_ok());
        for (s, e) in [(1.0 - 1e-6, 10.0), (1.0, 10.0 + 1e-6)] {
            let err = range(s, e, 1.0).check_within(1.0, 10.0).unwrap_err().to_string();
            assert!(err.contains("outside the stage's time range 1:10"), "{err}");
        }
    }
}
