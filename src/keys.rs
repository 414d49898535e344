//! Keyframes on stroke layers: configuration-space pose keys (Bassett §3.3)
//! and temporal keys bounded by sentinels (Bassett §3.4, SPEC §5).
//!
//! Pure math over plain arrays. Both kinds of key reduce to *weights*: a
//! channel value is `w_config · config + Σ w_k · key_k`, so one weight vector
//! blends every point of a layer (positions) or its opacity.

use crate::interp::{smooth_step, InterpError, Interpolator, Method, GAMMA};

/// Weighted sum of key values: `Σ w_k y_k` over (key index, weight) pairs.
pub type KeyWeights = Vec<(usize, f64)>;

/// A configuration-space channel: n keys at coordinates in R^d.
#[derive(Debug, Clone)]
pub struct PoseChannel {
    interp: Interpolator,
}

impl PoseChannel {
    /// Precomputes the interpolant of keys at `coords` (n × dim, row-major).
    pub fn new(method: Method, dim: usize, coords: &[f64]) -> Result<Self, InterpError> {
        Ok(PoseChannel {
            interp: Interpolator::new(method, dim, coords)?,
        })
    }

    /// Basis weights of each key at configuration `x`.
    pub fn weights(&self, x: &[f64]) -> KeyWeights {
        let w = self.interp.weights_vec(x);
        w.into_iter().enumerate().filter(|(_, w)| *w != 0.0).collect()
    }
}

/// One temporal key as the timeline sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeKey {
    /// Time code of the key.
    pub time: f64,
    /// Sentinels bound the keyed region and carry no data.
    pub sentinel: bool,
}

/// What the temporal keys say at one time: how much of the
/// configuration-space value stays, and the weights of normal keys.
#[derive(Debug, Clone, PartialEq)]
pub struct TemporalWeights {
    /// Weight of the configuration-space value (1 when inactive).
    pub config: f64,
    /// Weights of the channel's normal keys (indices into the channel's keys).
    pub keys: KeyWeights,
}

impl TemporalWeights {
    fn inactive() -> Self {
        TemporalWeights {
            config: 1.0,
            keys: Vec::new(),
        }
    }

    fn key(k: usize) -> Self {
        TemporalWeights {
            config: 0.0,
            keys: vec![(k, 1.0)],
        }
    }
}

/// Why a set of time keys cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub enum TimeKeyError {
    /// Two normal keys of one channel at the same time (indices into the channel's keys).
    SameTime { first: usize, second: usize },
    /// Two normal keys at different times that the interpolation of their
    /// group (the keys between two sentinels) counts as one time: closer
    /// than its duplicate tolerance ([`InterpError::DuplicateKeys`]).
    CloseTimes { first: usize, second: usize },
    /// A time that is not finite.
    NonFinite { key: usize },
    /// Two normal keys of one group so far apart in time that the squared
    /// distance between them overflows ([`InterpError::TooFarApart`]).
    FarApart { first: usize, second: usize },
    /// More normal keys in one group than [`crate::interp::MAX_KEYS`].
    TooMany { count: usize },
}

/// The temporal keys of one channel: its normal keys plus every sentinel.
#[derive(Debug, Clone)]
pub struct TimeChannel {
    /// Normal keys' times, in the order the caller gave them.
    key_times: Vec<f64>,
    /// Events sorted by time.
    events: Events,
    /// Per run of normal keys between two sentinels (or the ends of time):
    /// the keys' indices and their 1-D smooth Voronoi interpolant.
    groups: Vec<(Vec<usize>, Option<Interpolator>)>,
    /// Group of each normal key.
    group_of: Vec<usize>,
}

/// A channel's timeline: (time, Some(normal key index) or None for a sentinel).
type Events = Vec<(f64, Option<usize>)>;

/// The events of a channel sorted by time, and its runs of normal keys
/// between sentinels (finite times only; each key in exactly one run).
fn time_groups(key_times: &[f64], sentinels: &[f64]) -> (Events, Vec<Vec<usize>>) {
    let mut events: Events = key_times.iter().enumerate().map(|(i, &t)| (t, Some(i))).collect();
    events.extend(sentinels.iter().filter(|t| t.is_finite()).map(|&t| (t, None)));
    // At equal times a sentinel sorts first: the key after it is then
    // reached from the sentinel, and the key's own time gives its value.
    events.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.is_some().cmp(&b.1.is_some())));
    let mut groups = vec![Vec::new()];
    for &(_, e) in &events {
        match e {
            Some(k) => groups.last_mut().expect("one group at least").push(k),
            None => groups.push(Vec::new()),
        }
    }
    groups.retain(|g| !g.is_empty());
    (events, groups)
}

/// The other normal keys that count as the same time as key `k` (finite
/// times): those of its group within the group interpolation's duplicate
/// tolerance, as [`TimeChannel::new`] refuses them. A tool adding key `k`
/// learns which key it would meet.
pub fn same_time_as(key_times: &[f64], sentinels: &[f64], k: usize) -> Vec<usize> {
    if key_times.iter().any(|t| !t.is_finite()) {
        return Vec::new();
    }
    let (_, groups) = time_groups(key_times, sentinels);
    let Some(group) = groups.iter().find(|g| g.contains(&k)) else {
        return Vec::new();
    };
    let times: Vec<f64> = group.iter().map(|&i| key_times[i]).collect();
    let at = group.iter().position(|&i| i == k).expect("k is in its group");
    crate::interp::same_point_as(1, &times, at)
        .into_iter()
        .map(|j| group[j])
        .collect()
}

impl TimeChannel {
    /// `key_times`: the channel's normal keys; `sentinels`: every sentinel of the layer.
    pub fn new(key_times: &[f64], sentinels: &[f64]) -> Result<Self, TimeKeyError> {
        if let Some(k) = key_times.iter().position(|t| !t.is_finite()) {
            return Err(TimeKeyError::NonFinite { key: k });
        }
        for i in 0..key_times.len() {
            for j in i + 1..key_times.len() {
                if key_times[i] == key_times[j] {
                    return Err(TimeKeyError::SameTime { first: i, second: j });
                }
            }
        }
        let (events, runs) = time_groups(key_times, sentinels);
        let mut groups: Vec<(Vec<usize>, Option<Interpolator>)> = Vec::with_capacity(runs.len());
        let mut group_of = vec![0; key_times.len()];
        for members in runs {
            let coords: Vec<f64> = members.iter().map(|&k| key_times[k]).collect();
            // Distinct times can still be closer than the interpolation's
            // tolerance for their group's span: refused, not a panic.
            let interp = match (members.len() >= 2).then(|| Interpolator::new(Method::SmoothVoronoi, 1, &coords)) {
                None => None,
                Some(Ok(i)) => Some(i),
                Some(Err(InterpError::DuplicateKeys { first, second })) => {
                    let (a, b) = (members[first], members[second]);
                    return Err(TimeKeyError::CloseTimes {
                        first: a.min(b),
                        second: a.max(b),
                    });
                }
                Some(Err(InterpError::TooFarApart { first, second })) => {
                    let (a, b) = (members[first], members[second]);
                    return Err(TimeKeyError::FarApart {
                        first: a.min(b),
                        second: a.max(b),
                    });
                }
                Some(Err(InterpError::TooManyKeys { count })) => return Err(TimeKeyError::TooMany { count }),
                Some(Err(e)) => unreachable!("finite, distinct 1-D times: {e:?}"),
            };
            for &k in &members {
                group_of[k] = groups.len();
            }
            groups.push((members, interp));
        }
        Ok(TimeChannel {
            key_times: key_times.to_vec(),
            events,
            groups,
            group_of,
        })
    }

    /// The temporal weights at time `t` (SPEC §5).
    pub fn weights(&self, t: f64) -> TemporalWeights {
        if self.key_times.is_empty() {
            return TemporalWeights::inactive();
        }
        // Exactly on a normal key: its value.
        if let Some(k) = self.key_times.iter().position(|&kt| kt == t) {
            return TemporalWeights::key(k);
        }
        // prev: last event at or before t; next: first event after t.
        let split = self.events.partition_point(|e| e.0 <= t);
        let prev = split.checked_sub(1).map(|i| self.events[i]);
        let next = self.events.get(split).copied();
        match (prev, next) {
            // Before the first event / after the last one.
            (None, Some((_, Some(k)))) | (Some((_, Some(k))), None) => TemporalWeights::key(k),
            (None, Some((_, None))) | (Some((_, None)), None) | (None, None) => TemporalWeights::inactive(),
            // Between two sentinels: configuration space stands.
            (Some((_, None)), Some((_, None))) => TemporalWeights::inactive(),
            // Between two normal keys: 1-D smooth Voronoi over their group.
            (Some((_, Some(a))), Some((_, Some(_)))) => {
                let (members, interp) = &self.groups[self.group_of[a]];
                let interp = interp.as_ref().expect("a group with two adjacent keys has ≥ 2 keys");
                let w = interp.weights_vec(&[t]);
                TemporalWeights {
                    config: 0.0,
                    keys: members
                        .iter()
                        .zip(w)
                        .filter(|(_, w)| *w != 0.0)
                        .map(|(&k, w)| (k, w))
                        .collect(),
                }
            }
            // Sentinel → key or key → sentinel: blend with S_γ(u), u the
            // fraction of the way from the sentinel to the key.
            (Some((ts, None)), Some((tk, Some(k)))) | (Some((tk, Some(k))), Some((ts, None))) => {
                let u = (t - ts) / (tk - ts);
                let s = smooth_step(u, GAMMA);
                TemporalWeights {
                    config: 1.0 - s,
                    keys: if s != 0.0 { vec![(k, s)] } else { Vec::new() },
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(w: &TemporalWeights, config: f64, keys: &[f64]) -> f64 {
        w.config * config + w.keys.iter().map(|&(k, x)| x * keys[k]).sum::<f64>()
    }

    #[test]
    fn no_keys_is_inactive() {
        let c = TimeChannel::new(&[], &[5.0]).unwrap();
        assert_eq!(c.weights(3.0), TemporalWeights::inactive());
    }

    #[test]
    fn single_key_holds_everywhere_without_sentinels() {
        let c = TimeChannel::new(&[10.0], &[]).unwrap();
        for t in [0.0, 10.0, 50.0] {
            assert_eq!(c.weights(t), TemporalWeights::key(0));
        }
    }

    #[test]
    fn sentinel_blend_uses_the_smooth_step() {
        // Sentinel at 40, key at 48 (the SPEC's "shock" example).
        let c = TimeChannel::new(&[48.0], &[40.0]).unwrap();
        assert_eq!(c.weights(30.0), TemporalWeights::inactive());
        assert_eq!(c.weights(40.0).config, 1.0);
        let w = c.weights(44.0);
        // u = 0.5: S(0.5) = 0.5 for any γ.
        assert!((w.config - 0.5).abs() < 1e-12 && (w.keys[0].1 - 0.5).abs() < 1e-12);
        // u = 0.1 < γ: quadratic piece t² / (2γ(1−γ)).
        let w = c.weights(40.8);
        let expected = 0.01 / (2.0 * 0.2 * 0.8);
        assert!((w.keys[0].1 - expected).abs() < 1e-12);
        // After the last key, no sentinel beyond: the key holds.
        assert_eq!(c.weights(60.0), TemporalWeights::key(0));
    }

    #[test]
    fn key_then_sentinel_fades_back_to_configuration() {
        let c = TimeChannel::new(&[10.0], &[20.0]).unwrap();
        let w = c.weights(18.0);
        // u = fraction from the sentinel (20) towards the key (10) = 0.2.
        let s = 0.04 / (2.0 * 0.2 * 0.8);
        assert!((w.keys[0].1 - s).abs() < 1e-12);
        assert!((value(&w, 1.0, &[0.0]) - (1.0 - s)).abs() < 1e-12);
        assert_eq!(c.weights(25.0), TemporalWeights::inactive());
        assert_eq!(c.weights(5.0), TemporalWeights::key(0));
    }

    #[test]
    fn between_two_keys_interpolates_the_group_and_is_exact_at_keys() {
        let c = TimeChannel::new(&[10.0, 20.0, 30.0], &[0.0, 40.0]).unwrap();
        let keys = [1.0, 3.0, 2.0];
        assert_eq!(value(&c.weights(20.0), 0.0, &keys), 3.0);
        let mid = value(&c.weights(15.0), 0.0, &keys);
        assert!(mid > 1.0 && mid < 3.0, "{mid}");
        // Weights sum to 1 between keys (config weight 0).
        let w = c.weights(25.0);
        assert_eq!(w.config, 0.0);
        assert!((w.keys.iter().map(|k| k.1).sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn sentinel_splits_groups() {
        // Keys 10, 20 | sentinel 25 | keys 30, 40: between 20 and 30 there is
        // a sentinel, so 20→25 fades out and 25→30 fades in.
        let c = TimeChannel::new(&[10.0, 20.0, 30.0, 40.0], &[25.0]).unwrap();
        let w = c.weights(15.0);
        assert!(w.keys.iter().all(|&(k, _)| k < 2));
        assert_eq!(c.weights(25.0), TemporalWeights::inactive());
        let w = c.weights(35.0);
        assert!(w.keys.iter().all(|&(k, _)| k >= 2));
    }

    #[test]
    fn continuity_across_segment_boundaries() {
        let c = TimeChannel::new(&[10.0, 20.0], &[5.0, 30.0]).unwrap();
        let keys = [2.0, -1.0];
        let cfg = 0.5;
        for boundary in [5.0, 10.0, 20.0, 30.0] {
            let a = value(&c.weights(boundary - 1e-7), cfg, &keys);
            let b = value(&c.weights(boundary + 1e-7), cfg, &keys);
            assert!((a - b).abs() < 1e-5, "jump at {boundary}: {a} vs {b}");
        }
    }

    #[test]
    fn too_many_or_too_far_apart_time_keys_are_refused_not_a_panic() {
        let many: Vec<f64> = (0..=crate::interp::MAX_KEYS).map(|t| t as f64).collect();
        assert_eq!(
            TimeChannel::new(&many, &[]).unwrap_err(),
            TimeKeyError::TooMany {
                count: crate::interp::MAX_KEYS + 1
            }
        );
        // A sentinel splits them into two groups within the limit.
        assert!(TimeChannel::new(&many, &[100.5]).is_ok());
        // (1e160)² overflows: the pair is named by the channel's indices.
        assert_eq!(
            TimeChannel::new(&[5.0, 1e160, 0.0], &[]).unwrap_err(),
            TimeKeyError::FarApart { first: 1, second: 2 }
        );
        assert!(TimeChannel::new(&[5.0, 1e160, 0.0], &[10.0]).is_ok());
    }

    #[test]
    fn duplicate_times_are_rejected() {
        assert_eq!(
            TimeChannel::new(&[1.0, 2.0, 1.0], &[]).unwrap_err(),
            TimeKeyError::SameTime { first: 0, second: 2 }
        );
    }

    #[test]
    fn times_the_interpolation_counts_as_one_are_rejected() {
        // 1e-7 apart in a group spanning 1e6: within 1e-12 of the span.
        assert_eq!(
            TimeChannel::new(&[1e6 + 1e-7, 0.0, 1e6], &[]).unwrap_err(),
            TimeKeyError::CloseTimes { first: 0, second: 2 }
        );
        // 1e-5 apart: farther than 1e-12 of the span.
        assert!(TimeChannel::new(&[1e6 + 1e-5, 0.0, 1e6], &[]).is_ok());
        // A sentinel between 0 and 1e6 leaves the pair a group of its own,
        // spanning 1e-7: two times.
        assert!(TimeChannel::new(&[1e6 + 1e-7, 0.0, 1e6], &[5.0]).is_ok());
        assert_eq!(same_time_as(&[1e6 + 1e-7, 0.0, 1e6], &[], 2), vec![0]);
        assert_eq!(same_time_as(&[1e6 + 1e-7, 0.0, 1e6], &[], 1), Vec::<usize>::new());
        assert_eq!(same_time_as(&[1e6 + 1e-7, 0.0, 1e6], &[5.0], 2), Vec::<usize>::new());
        // Equal times meet in any group, and a sentinel at their time
        // does not part them (it sorts before both).
        assert_eq!(same_time_as(&[3.0, 3.0], &[3.0], 0), vec![1]);
        assert!(same_time_as(&[3.0, f64::NAN], &[], 0).is_empty());
        // The rule same_time_as reports is the one new() enforces.
        for (times, sentinels) in [
            (vec![0.0, 44.0, 44.0 + 5e-12], vec![]),
            (vec![0.0, 44.0, 44.0 + 5e-11], vec![]),
            (vec![37.0, 40.0, 44.0, 44.0 + 5e-12], vec![36.0, 47.0]),
            (vec![40.0, 44.0 + 5e-12, 1e9, 44.0], vec![36.0, 47.0]),
        ] {
            let met = (0..times.len()).any(|k| !same_time_as(&times, &sentinels, k).is_empty());
            assert_eq!(
                met,
                TimeChannel::new(&times, &sentinels).is_err(),
                "{times:?} {sentinels:?}"
            );
        }
    }
}

/// Combines configuration-space weights (over pose keys, or `None` for "the
/// layer's rest value") with temporal weights (over time keys): returns the
/// final (weight, [`Source`]) terms.
pub fn combine(config: Option<&KeyWeights>, temporal: Option<&TemporalWeights>) -> Vec<(f64, Source)> {
    let mut out = Vec::new();
    let cw = temporal.map_or(1.0, |t| t.config);
    if cw != 0.0 {
        match config {
            None => out.push((cw, Source::Rest)),
            Some(w) => out.extend(w.iter().map(|&(k, x)| (cw * x, Source::Pose(k)))),
        }
    }
    if let Some(t) = temporal {
        out.extend(t.keys.iter().map(|&(k, x)| (x, Source::Time(k))));
    }
    out
}

/// Where a blended value comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The layer's rest value (rest points, opacity 1).
    Rest,
    /// Pose key k of the channel.
    Pose(usize),
    /// Normal time key k of the channel.
    Time(usize),
}

#[cfg(test)]
mod combine_tests {
    use super::*;

    #[test]
    fn temporal_override_scales_configuration_terms() {
        let cfg = vec![(0, 0.25), (1, 0.75)];
        let tw = TemporalWeights {
            config: 0.4,
            keys: vec![(0, 0.6)],
        };
        let c = combine(Some(&cfg), Some(&tw));
        assert_eq!(
            c,
            vec![
                (0.1, Source::Pose(0)),
                (0.30000000000000004, Source::Pose(1)),
                (0.6, Source::Time(0))
            ]
        );
        assert_eq!(combine(None, None), vec![(1.0, Source::Rest)]);
    }
}
