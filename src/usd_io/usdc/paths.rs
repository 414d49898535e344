//! The PATHS section: every path the file names, as a tree.
//!
//! Each path is stored as its parent plus one element token, exactly as
//! usd-core's `SdfPath` splits it: `GetElementToken()` (`B`, `{set=sel}`,
//! `[/Target]`, `.relAttr`, `.mapper[/T.x]`), except that a prim property
//! stores its bare name with a negative token index. usd-core's in-place
//! save re-derives these tokens from the paths it read and looks each up in
//! the file's token table (`_GetIndexForToken`), so the table must hold every
//! one of them, the pseudo-root's empty token included; and every path's
//! parent must be in the table too, or the tree it re-encodes loses the
//! subtree. Interning a path here interns its whole ancestor chain and every
//! element token.

use std::collections::HashMap;

use super::compress::put_compressed_ints;
use super::tables::Tokens;

/// The kind of a path's last element, which decides how usd-core appends it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Prim,
    Variant,
    /// A property of a prim (or of a variant selection): stored by name.
    PrimProperty,
    /// Any other `.name` element: a relational attribute, a mapper argument,
    /// an expression.
    SubProperty,
    Target,
    Mapper,
}

struct Entry {
    /// The element's index in the token table (the pseudo-root's is `""`).
    token: u32,
    prim_property: bool,
    /// `false` for the empty path, which has a slot but no place in the tree.
    in_tree: bool,
    children: Vec<u32>,
}

/// Interned paths, by slot: 0 is the pseudo-root, every other path's parent
/// comes before it.
pub struct Paths {
    index: HashMap<String, u32>,
    strings: Vec<String>,
    entries: Vec<Entry>,
}

impl Paths {
    /// A table holding the pseudo-root, whose element token (`""`) is interned.
    pub fn new(tokens: &mut Tokens) -> Paths {
        let root_token = tokens.intern("");
        let mut index = HashMap::new();
        index.insert("/".to_string(), 0);
        Paths {
            index,
            strings: vec!["/".to_string()],
            entries: vec![Entry {
                token: root_token,
                prim_property: false,
                in_tree: true,
                children: Vec::new(),
            }],
        }
    }

    /// The slot of `path`, interning it, its ancestors and (for a target
    /// path) its target, as usd-core's `_AddPath` does.
    pub fn intern(&mut self, path: &str, tokens: &mut Tokens) -> Result<u32, String> {
        if let Some(&i) = self.index.get(path) {
            return Ok(i);
        }
        if path.is_empty() {
            // A reference or payload without a prim path: usd-core keeps a
            // slot for it (element token `""`) and leaves it out of the tree.
            let token = tokens.intern("");
            return Ok(self.push(path, token, false, false));
        }
        let (parent, element, kind) = split_last(path)?;
        if kind == Kind::Target {
            self.intern(&element[1..element.len() - 1], tokens)?;
        }
        let parent_slot = self.intern(parent, tokens)?;
        let token = match kind {
            Kind::PrimProperty => tokens.intern(&element[1..]),
            _ => tokens.intern(element),
        };
        let slot = self.push(path, token, kind == Kind::PrimProperty, true);
        self.entries[parent_slot as usize].children.push(slot);
        Ok(slot)
    }

    fn push(&mut self, path: &str, token: u32, prim_property: bool, in_tree: bool) -> u32 {
        let slot = self.entries.len() as u32;
        self.index.insert(path.to_string(), slot);
        self.strings.push(path.to_string());
        self.entries.push(Entry {
            token,
            prim_property,
            in_tree,
            children: Vec::new(),
        });
        slot
    }

    /// Appends the PATHS section body: the slot count, the encoded count,
    /// then the compressed path slots, element token indexes (negative for
    /// prim properties) and jumps (-2 leaf, -1 child only, 0 sibling only,
    /// else the distance to the next sibling) of a depth-first walk.
    pub fn write_section(&mut self, out: &mut Vec<u8>) {
        // Children in path order: any order reads back, this one is stable.
        let strings = &self.strings;
        for e in &mut self.entries {
            e.children
                .sort_by(|a, b| strings[*a as usize].cmp(&strings[*b as usize]));
        }
        let slots = self.entries.len();
        let mut next_sibling: Vec<Option<u32>> = vec![None; slots];
        for e in &self.entries {
            for pair in e.children.windows(2) {
                next_sibling[pair[0] as usize] = Some(pair[1]);
            }
        }
        // Pre-order walk: each node, then its subtree, then its next sibling.
        let mut order: Vec<u32> = Vec::with_capacity(slots);
        let mut position: Vec<usize> = vec![usize::MAX; slots];
        let mut stack: Vec<u32> = vec![0];
        while let Some(slot) = stack.pop() {
            position[slot as usize] = order.len();
            order.push(slot);
            stack.extend(self.entries[slot as usize].children.iter().rev());
        }
        debug_assert_eq!(order.len(), self.entries.iter().filter(|e| e.in_tree).count());
        let mut element_tokens: Vec<i32> = Vec::with_capacity(order.len());
        let mut jumps: Vec<i32> = Vec::with_capacity(order.len());
        for (here, &slot) in order.iter().enumerate() {
            let e = &self.entries[slot as usize];
            let token = e.token as i32;
            element_tokens.push(if e.prim_property { -token } else { token });
            jumps.push(match (!e.children.is_empty(), next_sibling[slot as usize]) {
                (true, Some(sib)) => (position[sib as usize] - here) as i32,
                (true, None) => -1,
                (false, Some(_)) => 0,
                (false, None) => -2,
            });
        }
        out.extend_from_slice(&(slots as u64).to_le_bytes());
        out.extend_from_slice(&(order.len() as u64).to_le_bytes());
        put_compressed_ints(&order, out);
        put_compressed_ints(&element_tokens, out);
        put_compressed_ints(&jumps, out);
    }
}

/// Splits an absolute path into its parent, its last element as usd-core
/// spells it (`B`, `{set=sel}`, `.prop`, `[/target]`, `.mapper[/x.y]`) and
/// the element's kind. Brackets are matched, so a target path may contain
/// any path.
fn split_last(path: &str) -> Result<(&str, &str, Kind), String> {
    let b = path.as_bytes();
    if b.first() != Some(&b'/') {
        return Err(format!("path <{path}> is not absolute"));
    }
    if path == "/" {
        return Err("the pseudo-root has no parent".into());
    }
    // Walk the elements left to right: (start, end, kind) of the last one and
    // the kind before it.
    let mut i = 1;
    let mut last: Option<(usize, usize, Kind)> = None;
    let bad = |why: &str| format!("path <{path}> is malformed: {why}");
    while i < b.len() {
        let kind_before = last.map(|l| l.2);
        let (start, end, kind) = match b[i] {
            b'/' => {
                if matches!(kind_before, None | Some(Kind::Variant)) {
                    return Err(bad("'/' where a prim name is expected"));
                }
                let end = scan_name(b, i + 1);
                if end == i + 1 {
                    return Err(bad("empty prim name"));
                }
                (i, end, Kind::Prim)
            }
            b'{' => {
                let close = b[i..]
                    .iter()
                    .position(|&c| c == b'}')
                    .ok_or_else(|| bad("unclosed '{'"))?
                    + i;
                (i, close + 1, Kind::Variant)
            }
            b'.' => {
                let end = scan_name(b, i + 1);
                if end == i + 1 {
                    return Err(bad("empty property name"));
                }
                let name = &path[i + 1..end];
                if name == "mapper" && b.get(end) == Some(&b'[') {
                    let close = matching_bracket(b, end).ok_or_else(|| bad("unclosed '['"))?;
                    (i, close + 1, Kind::Mapper)
                } else if matches!(kind_before, Some(Kind::Prim) | Some(Kind::Variant)) {
                    (i, end, Kind::PrimProperty)
                } else {
                    (i, end, Kind::SubProperty)
                }
            }
            b'[' => {
                let close = matching_bracket(b, i).ok_or_else(|| bad("unclosed '['"))?;
                (i, close + 1, Kind::Target)
            }
            _ => {
                // A prim name right after `/` (the first) or after a variant
                // selection (`/A{v=x}B`).
                if !matches!(kind_before, None | Some(Kind::Variant)) {
                    return Err(bad("unexpected character"));
                }
                let end = scan_name(b, i);
                (i, end, Kind::Prim)
            }
        };
        if end <= i {
            return Err(bad("empty element"));
        }
        last = Some((start, end, kind));
        i = end;
    }
    let (start, end, kind) = last.ok_or_else(|| bad("no element"))?;
    let (parent, element) = match kind {
        Kind::Prim if b[start] == b'/' => {
            let parent = if start == 0 { "/" } else { &path[..start] };
            (parent, &path[start + 1..end])
        }
        Kind::Prim => {
            let parent = if start <= 1 { "/" } else { &path[..start] };
            (parent, &path[start..end])
        }
        _ => (&path[..start], &path[start..end]),
    };
    Ok((parent, element, kind))
}

/// End of a prim or property name starting at `i`: up to the next `/`, `.`,
/// `{`, `[`, `]` or the end.
fn scan_name(b: &[u8], i: usize) -> usize {
    let mut j = i;
    while j < b.len() && !matches!(b[j], b'/' | b'.' | b'{' | b'[' | b']') {
        j += 1;
    }
    j
}

/// Index of the `]` matching the `[` at `open`.
fn matching_bracket(b: &[u8], open: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (k, &c) in b.iter().enumerate().skip(open) {
        match c {
            b'[' => depth += 1,
            b']' => {
                depth -= 1;
                if depth == 0 {
                    return Some(k);
                }
            }
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parents and element tokens as usd-core 26.11 reports them
    /// (`Sdf.Path(p).GetParentPath()`, `.elementString`, `.name` for prim
    /// properties; printed on this machine).
    #[test]
    fn splits_like_usd_core() {
        let cases = [
            ("/A", "/", "A", Kind::Prim),
            ("/A/B", "/A", "B", Kind::Prim),
            ("/A.b", "/A", ".b", Kind::PrimProperty),
            ("/A.b:c:d", "/A", ".b:c:d", Kind::PrimProperty),
            ("/A{v=x}", "/A", "{v=x}", Kind::Variant),
            ("/A{v=}", "/A", "{v=}", Kind::Variant),
            ("/A{v=x}B", "/A{v=x}", "B", Kind::Prim),
            ("/A{v=x}{w=y}", "/A{v=x}", "{w=y}", Kind::Variant),
            ("/A{v=x}.p", "/A{v=x}", ".p", Kind::PrimProperty),
            ("/A{v=x}B.c", "/A{v=x}B", ".c", Kind::PrimProperty),
            ("/A.rel[/T]", "/A.rel", "[/T]", Kind::Target),
            ("/A.rel[/T.x]", "/A.rel", "[/T.x]", Kind::Target),
            ("/A.rel[/T].attr", "/A.rel[/T]", ".attr", Kind::SubProperty),
            ("/A.attr.mapper[/T.x]", "/A.attr", ".mapper[/T.x]", Kind::Mapper),
            (
                "/A.attr.mapper[/T.x].arg",
                "/A.attr.mapper[/T.x]",
                ".arg",
                Kind::SubProperty,
            ),
            ("/A.attr.expression", "/A.attr", ".expression", Kind::SubProperty),
            ("/A.rel[/B.rel2[/C]]", "/A.rel", "[/B.rel2[/C]]", Kind::Target),
        ];
        for (path, parent, element, kind) in cases {
            assert_eq!(split_last(path), Ok((parent, element, kind)), "{path}");
        }
        assert!(split_last("A/B").is_err());
        assert!(split_last("/A.rel[/T").is_err());
    }

    /// An empty prim or property name makes a path usd-core refuses
    /// (`Sdf.Path(p).isEmpty` for each of these).
    #[test]
    fn empty_names_are_refused() {
        for path in ["/A//B", "/A/", "/A.", "/A..b"] {
            assert!(split_last(path).is_err(), "{path}");
        }
    }

    /// usd-core's `_AddPath` adds a target path's target (`/T.x` of
    /// `/A.rel[/T.x]`) with its ancestors, besides the path's own parents.
    #[test]
    fn a_target_path_interns_its_target() {
        let mut tokens = Tokens::new();
        let mut paths = Paths::new(&mut tokens);
        let slot = paths.intern("/A.rel[/T.x]", &mut tokens).unwrap();
        for p in ["/", "/A", "/A.rel", "/T", "/T.x"] {
            let at = paths.index.get(p).copied();
            assert!(at.is_some_and(|i| i < slot), "{p} not interned before the target path");
        }
        assert_eq!(paths.strings.len(), 6);
    }
}
