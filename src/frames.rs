//! Frame ranges: `A`, `A:B` or `A:B:STEP`, in the stage's time codes.

use crate::error::{Error, Result};

/// The most time codes one range may hold: far beyond any shot (11.5 hours
/// at 24 fps), and small enough that listing them cannot exhaust memory.
pub const MAX_TIME_CODES: f64 = 1_000_000.0;

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
        if step <= 0.0 {
            return Err(format!("step {step} must be positive"));
        }
        if end < start {
            return Err(format!("end {end} is before start {start}"));
        }
        let range = FrameRange { start, end, step };
        range.check_count()?;
        Ok(range)
    }
}

impl FrameRange {
    /// The time codes of the range, start first; the end is included when the
    /// step lands on it (within 1e-9).
    pub fn times(&self) -> Vec<f64> {
        let n = ((self.end - self.start) / self.step + 1e-9).floor() as usize + 1;
        (0..n).map(|k| self.start + k as f64 * self.step).collect()
    }

    /// Refuses a range of more than [`MAX_TIME_CODES`] time codes (a tiny
    /// step or a huge span), before anything is allocated for it.
    pub fn check_count(&self) -> std::result::Result<(), String> {
        let count = (self.end - self.start) / self.step + 1.0;
        if count.is_finite() && count <= MAX_TIME_CODES {
            Ok(())
        } else {
            Err(format!(
                "{}:{}:{} holds {count:.0} time codes; at most {MAX_TIME_CODES} are allowed (use a larger step or bake in parts)",
                self.start, self.end, self.step
            ))
        }
    }

    /// Checks the range lies within the stage's authored [start, end].
    pub fn check_within(&self, stage_start: f64, stage_end: f64) -> Result<()> {
        if self.start < stage_start - 1e-9 || self.end > stage_end + 1e-9 {
            return Err(Error::msg(format!(
                "--frames {}:{} is outside the stage's time range {}:{} (startTimeCode:endTimeCode)",
                self.start, self.end, stage_start, stage_end
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            "1:24:1e-9",
            "0:1e300",
        ] {
            assert!(bad.parse::<FrameRange>().is_err(), "{bad}");
        }
    }
}
