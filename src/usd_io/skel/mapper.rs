//! usd-core's `UsdSkelAnimMapper`: how an array in one name order (an
//! animation's joints or blend shapes, a skeleton's joints) lands in another.
//! Duplicated and unknown names follow its rules exactly, since they decide
//! which joint a mesh follows.

use std::collections::HashMap;

/// usd-core's `UsdSkelAnimMapper`: where the elements of an array in one
/// name order land in another.
#[derive(Debug, Clone)]
pub(super) struct OrderMap {
    pub(super) target_len: usize,
    kind: MapKind,
    /// Whether some target element receives no source element.
    pub(super) sparse: bool,
}

#[derive(Debug, Clone)]
enum MapKind {
    /// Nothing maps (an empty order on either side).
    Null,
    /// The source order is a contiguous run of the target order at this offset.
    Ordered(usize),
    /// Target index of each source element (by name; the last of duplicated
    /// target names wins).
    Indexed(Vec<Option<usize>>),
}

impl OrderMap {
    pub(super) fn new(source: &[String], target: &[String]) -> OrderMap {
        let target_len = target.len();
        if source.is_empty() || target.is_empty() {
            return OrderMap {
                target_len,
                kind: MapKind::Null,
                sparse: true,
            };
        }
        if let Some(pos) = target.iter().position(|t| *t == source[0]) {
            if pos + source.len() <= target_len && target[pos..pos + source.len()] == *source {
                return OrderMap {
                    target_len,
                    kind: MapKind::Ordered(pos),
                    sparse: !(pos == 0 && source.len() == target_len),
                };
            }
        }
        let mut by_name = HashMap::new();
        for (i, t) in target.iter().enumerate() {
            by_name.insert(t.as_str(), i);
        }
        let idx: Vec<Option<usize>> = source.iter().map(|s| by_name.get(s.as_str()).copied()).collect();
        let mut covered = vec![false; target_len];
        for &i in idx.iter().flatten() {
            covered[i] = true;
        }
        OrderMap {
            target_len,
            kind: MapKind::Indexed(idx),
            sparse: covered.contains(&false),
        }
    }

    pub(super) fn is_null(&self) -> bool {
        matches!(self.kind, MapKind::Null)
    }

    /// Copies `source` into `target`, first resized to the target order
    /// (new elements `default`); elements no source reaches keep their value.
    pub(super) fn remap<T: Clone>(&self, source: &[T], target: &mut Vec<T>, default: T) {
        target.resize(self.target_len, default);
        match &self.kind {
            MapKind::Null => {}
            MapKind::Ordered(off) => {
                let n = source.len().min(self.target_len - off);
                target[*off..off + n].clone_from_slice(&source[..n]);
            }
            MapKind::Indexed(idx) => {
                for (s, ti) in source.iter().zip(idx) {
                    if let Some(ti) = ti {
                        target[*ti] = s.clone();
                    }
                }
            }
        }
    }

    /// Source index feeding each target element, if any.
    pub(super) fn sources(&self, source_len: usize) -> Vec<Option<usize>> {
        let mut out = Vec::new();
        self.remap(&(0..source_len).map(Some).collect::<Vec<_>>(), &mut out, None);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(s: &[&str]) -> Vec<String> {
        s.iter().map(|s| s.to_string()).collect()
    }

    fn remap(source: &[&str], target: &[&str], start: Vec<i32>) -> Vec<i32> {
        let map = OrderMap::new(&names(source), &names(target));
        let values: Vec<i32> = (1..=source.len() as i32).collect();
        let mut out = start;
        map.remap(&values, &mut out, 0);
        out
    }

    #[test]
    fn ordered_runs_copy_at_their_offset() {
        assert_eq!(remap(&["b", "c"], &["a", "b", "c", "d"], vec![]), vec![0, 1, 2, 0]);
        let m = OrderMap::new(&names(&["a", "b"]), &names(&["a", "b"]));
        assert!(!m.sparse && !m.is_null());
        assert!(OrderMap::new(&names(&["b"]), &names(&["a", "b"])).sparse);
    }

    #[test]
    fn indexed_maps_by_name_last_duplicate_wins() {
        // "b" appears twice in the target: only the last receives it.
        assert_eq!(remap(&["a", "b"], &["b", "a", "b"], vec![]), vec![0, 1, 2]);
        // Duplicated source names: the later source element overwrites.
        assert_eq!(remap(&["x", "a", "a"], &["a", "y"], vec![]), vec![3, 0]);
        // Unmapped targets keep what was there (e.g. rest transforms).
        assert_eq!(remap(&["c", "a"], &["a", "b", "c"], vec![7, 8, 9]), vec![2, 8, 1]);
    }

    #[test]
    fn short_sources_copy_what_they_have() {
        let map = OrderMap::new(&names(&["a", "b", "c"]), &names(&["a", "b", "c"]));
        let mut out = Vec::new();
        map.remap(&[5], &mut out, 0);
        assert_eq!(out, vec![5, 0, 0]);
    }

    #[test]
    fn empty_orders_map_nothing() {
        assert!(OrderMap::new(&[], &names(&["a"])).is_null());
        assert_eq!(remap(&["a"], &[], vec![]), Vec::<i32>::new());
    }

    #[test]
    fn long_sources_copy_only_what_fits() {
        // usd-core: AnimMapper(["b", "c"], ["a", "b", "c"]).Remap([1, 2, 3]) is [0, 1, 2].
        let map = OrderMap::new(&names(&["b", "c"]), &names(&["a", "b", "c"]));
        let mut out = Vec::new();
        map.remap(&[1, 2, 3], &mut out, 0);
        assert_eq!(out, vec![0, 1, 2]);
    }

    #[test]
    fn sources_name_the_source_index_of_each_target() {
        // usd-core: AnimMapper(["c", "a"], ["a", "b", "c"]).Remap([0, 1], defaultValue=-1) is [1, -1, 0].
        let map = OrderMap::new(&names(&["c", "a"]), &names(&["a", "b", "c"]));
        assert_eq!(map.sources(2), vec![Some(1), None, Some(0)]);
        let map = OrderMap::new(&names(&["b", "c"]), &names(&["a", "b", "c", "d"]));
        assert_eq!(map.sources(2), vec![None, Some(0), Some(1), None]);
    }
}
