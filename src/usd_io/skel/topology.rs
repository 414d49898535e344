//! Skeleton topology as usd-core's `UsdSkelTopology` reads it from joint
//! names, and its validation.

use std::collections::HashMap;

use crate::error::{Error, Result};

/// Whether a joint name is a well-formed relative or absolute prim path:
/// usd-core gives ill-formed names (spaces, dots, `a//b`) no parent.
fn is_prim_path(name: &str) -> bool {
    let body = name.strip_prefix('/').unwrap_or(name);
    !body.is_empty() && body.split('/').all(crate::usd_io::is_prim_name)
}

/// Parent of each joint as usd-core's UsdSkelTopology finds it: the nearest
/// ancestor path listed in `joints` (the last joint of that name).
pub fn joint_parents(joints: &[String]) -> Vec<Option<usize>> {
    let mut by_name = HashMap::new();
    for (i, j) in joints.iter().enumerate() {
        by_name.insert(j.as_str(), i);
    }
    joints
        .iter()
        .map(|j| {
            if !is_prim_path(j) {
                return None;
            }
            let mut cur = j.as_str();
            while let Some((parent, _)) = cur.rsplit_once('/') {
                if parent.is_empty() {
                    break;
                }
                if let Some(&p) = by_name.get(parent) {
                    return Some(p);
                }
                cur = parent;
            }
            None
        })
        .collect()
}

/// usd-core's UsdSkelTopology::Validate: every parent before its child.
pub(super) fn validate_topology(skeleton: &str, joints: &[String], parents: &[Option<usize>]) -> Result<()> {
    for (j, p) in parents.iter().enumerate() {
        if let Some(p) = *p {
            if p >= j {
                let why = if p == j {
                    "is its own parent".to_string()
                } else if joints[..j].contains(&joints[p]) {
                    format!(
                        "has its parent {:?} listed again after it (duplicate joint name)",
                        joints[p]
                    )
                } else {
                    format!("comes before its parent {:?} (joint {p})", joints[p])
                };
                return Err(Error::attr(
                    skeleton,
                    "joints",
                    format!("joint {j} {:?} {why}: parents must come before their children (usd-core rejects this skeleton)", joints[j]),
                ));
            }
        }
    }
    Ok(())
}

/// Names listed more than once (for notes).
pub(super) fn duplicates(names: &[String]) -> Vec<&str> {
    let mut seen = HashMap::new();
    let mut out = Vec::new();
    for n in names {
        let c = seen.entry(n.as_str()).or_insert(0);
        *c += 1;
        if *c == 2 {
            out.push(n.as_str());
        }
    }
    out
}

pub(super) fn quoted(names: &[&str]) -> String {
    names.iter().map(|n| format!("{n:?}")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(s: &[&str]) -> Vec<String> {
        s.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn parents_are_the_nearest_listed_ancestor() {
        // Values checked against usd-core's UsdSkel.Topology(...).GetParentIndices().
        let cases: &[(&[&str], &[Option<usize>])] = &[
            (&["a", "a/b", "a/b/c"], &[None, Some(0), Some(1)]),
            (&["a", "a/x/b", "a/x/b/c"], &[None, Some(0), Some(1)]),
            (&["a", "a/b", "a/b"], &[None, Some(0), Some(0)]),
            (&["/r", "/r/s", "r/s"], &[None, Some(0), None]),
            (&["a", "a/b.1", "a/b.1/c"], &[None, None, None]),
            (&["a", "a b", "a/b c"], &[None, None, None]),
            (&["a", "0a", "a/0b"], &[None, None, None]),
            (&["a", "a/", "a//b"], &[None, None, None]),
            (&["ä", "ä/ö"], &[None, Some(0)]),
        ];
        for (joints, parents) in cases {
            assert_eq!(joint_parents(&names(joints)), parents.to_vec(), "{joints:?}");
        }
    }

    #[test]
    fn children_before_parents_are_rejected() {
        let j = names(&["a/b", "a"]);
        let e = validate_topology("/S", &j, &joint_parents(&j)).unwrap_err();
        assert_eq!(e.attribute.as_deref(), Some("joints"));
        // A duplicate of the parent listed after the child moves the parent.
        let j = names(&["a", "a/b", "a"]);
        assert!(validate_topology("/S", &j, &joint_parents(&j)).is_err());
        let j = names(&["a", "a/b", "a/b"]);
        assert!(validate_topology("/S", &j, &joint_parents(&j)).is_ok());
    }

    #[test]
    fn longer_joint_names_find_their_parents() {
        // usd-core: UsdSkel.Topology(these).GetParentIndices() is [-1, 0, 1, -1, 3].
        let j = names(&["root", "root/arm_1", "root/arm_1/hand2", "Hips", "Hips/Spine"]);
        assert_eq!(joint_parents(&j), vec![None, Some(0), Some(1), None, Some(3)]);
    }

    #[test]
    fn rejection_says_why() {
        let why = |j: &[&str]| {
            let j = names(j);
            validate_topology("/S", &j, &joint_parents(&j)).unwrap_err().to_string()
        };
        let e = why(&["a/b", "a"]);
        assert!(e.contains(r#"comes before its parent "a""#), "{e}");
        let e = why(&["a", "a/b", "a"]);
        assert!(e.contains("duplicate joint name"), "{e}");
    }
}
