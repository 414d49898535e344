//! Composition guards: what painterly checks so that openusd 0.8 never
//! overflows the stack or runs for hours on a file usd-core would open.
//!
//! Measured on openusd 0.8 (see README, "Limits"):
//!
//! - its `.usda` parser recurses once per nesting level and overflows the
//!   main thread's 8 MB stack near 10,000 nested blocks;
//! - composing a chain of nested prims costs O(depth³) (500 levels 0.3–1.3 s,
//!   2,000 levels a minute);
//! - `IndexCache::precache_inherit_targets` follows inherit/specialize
//!   targets recursively without a visited set, so two classes inheriting
//!   each other (or a class inheriting itself) recurse until the stack
//!   overflows. usd-core reports such cycles as composition errors.
//!
//! The guard sits in front of openusd as an [`ar::Resolver`] that sees the
//! bytes of every layer before openusd parses it, so it checks every layer
//! the stage opens (root, sublayers, references, payloads, package entries)
//! exactly as openusd resolves them:
//!
//! 1. text nesting deeper than [`MAX_TEXT_NESTING`] is refused before parsing;
//! 2. a namespace deeper than [`MAX_NAMESPACE_DEPTH`] is refused before
//!    composition;
//! 3. inherit/specialize arcs of all layers are collected into one graph; a
//!    cycle is refused before composition. Whatever else openusd cannot
//!    compose is caught while composing by [`super::compose_watch`].
//!
//! Root-stack layers are checked from the stage's own parse (between
//! `Stage::open` and the first traversal); layers loaded later by
//! composition are parsed once more here before openusd composes them, and
//! are withheld from the stage (the load fails) when they break a rule. The
//! problem is recorded and reported by [`super::stage::StageReader::open`].

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::io;
use std::rc::Rc;

use openusd::ar::{self, Asset, AssetBuffer, ResolvedPath};
use openusd::sdf::{self, AbstractData, Value};

use super::usda_text;
use crate::error::Error;

/// Deepest prim namespace painterly composes (prims below the root: `/A/B`
/// is depth 2). A 256-deep chain composes in about 0.4 s; real assets stay
/// well under 50.
pub const MAX_NAMESPACE_DEPTH: usize = 256;

/// Deepest bracket nesting (`(`, `[`, `{`) accepted in `.usda` text. Room for
/// [`MAX_NAMESPACE_DEPTH`] prims inside variant sets (3 brackets per level)
/// and far below the ~10,000 levels where openusd's parser overflows.
pub const MAX_TEXT_NESTING: usize = 1000;

/// Most stroke points painterly bakes in one run (all layers together). A
/// 48-frame bake holds about 130 bytes per stroke point, frames in flight
/// included (`scripts/bench_memory --sizes`), so about 2.6 GB at the limit.
pub const MAX_STROKE_POINTS: usize = 20_000_000;

/// Most points of one rig proxy: binding and the rotation fits peak at about
/// 720 bytes per proxy vertex (`scripts/bench_memory --sizes`), so about
/// 7 GB at the limit.
pub const MAX_PROXY_POINTS: usize = 10_000_000;

/// What the guard has seen and found.
#[derive(Default)]
struct State {
    /// Set once the root stack is checked: later layers come from composition
    /// and are parsed here before openusd uses them.
    composing: bool,
    /// Problems found, in order.
    problems: Vec<Error>,
    /// Inherit/specialize targets authored at each prim path (variant
    /// selections stripped), with the layer that authors them.
    targets: HashMap<String, Vec<(String, String)>>,
    /// Layers already scanned (by identifier).
    scanned: HashSet<String>,
    /// Each file opened, as it was just before it was read.
    opened: OpenedFiles,
    /// Whether a layer read may author a spline ([`may_hold_splines`]).
    splines: bool,
}

/// Files a stage read, each with its version just before it was read.
pub type OpenedFiles = std::collections::BTreeMap<std::path::PathBuf, FileId>;

/// What tells a file's version apart without reading it: a save by rename
/// gives a new inode, one in place a new size or modification time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileId {
    dev: u64,
    ino: u64,
    len: u64,
    mtime_ns: i128,
}

/// A file time (seconds and nanoseconds, as `stat` gives them) in nanoseconds.
pub fn nanoseconds(secs: i64, nsec: i64) -> i128 {
    i128::from(secs) * 1_000_000_000 + i128::from(nsec)
}

impl FileId {
    /// The file at `path` now, through links; None when it cannot be seen.
    pub fn of(path: &std::path::Path) -> Option<FileId> {
        Some(FileId::from_metadata(&std::fs::metadata(path).ok()?))
    }

    /// The file `m` describes (of a file already open, say).
    pub fn from_metadata(m: &std::fs::Metadata) -> FileId {
        use std::os::unix::fs::MetadataExt;
        FileId {
            dev: m.dev(),
            ino: m.ino(),
            len: m.len(),
            mtime_ns: nanoseconds(m.mtime(), m.mtime_nsec()),
        }
    }

    /// Whether `other` is a version of the same file (device and inode).
    pub fn same_file(&self, other: &FileId) -> bool {
        (self.dev, self.ino) == (other.dev, other.ino)
    }
}

/// Shared handle to the guard's findings.
#[derive(Clone, Default)]
pub struct Guard {
    state: Rc<RefCell<State>>,
}

impl Guard {
    /// A resolver (the default one, opening regular files only, guarded)
    /// reporting into this guard.
    pub fn resolver(&self) -> GuardedResolver {
        self.resolver_over(super::regular::RegularResolver::new())
    }

    /// `inner` (e.g. the resolver of a layer handed over in memory),
    /// guarded, reporting into this guard.
    pub fn resolver_over<R: ar::Resolver>(&self, inner: R) -> GuardedResolver<R> {
        GuardedResolver {
            inner,
            guard: self.clone(),
        }
    }

    /// Every file read so far (a package once, by its own path), as it was
    /// just before it was read.
    pub fn opened_files(&self) -> OpenedFiles {
        self.state.borrow().opened.clone()
    }

    /// Notes the version of the file behind `resolved` (a package for
    /// `pkg.usdz[inner.usda]`) the first time it is read.
    fn note_opened(&self, resolved: &ResolvedPath) {
        let text = resolved.to_str().unwrap_or_default();
        let file = std::path::PathBuf::from(super::stage::package_file(text));
        if self.state.borrow().opened.contains_key(&file) {
            return;
        }
        if let Some(id) = FileId::of(&file) {
            self.state.borrow_mut().opened.insert(file, id);
        }
    }

    /// Whether some layer read so far may author a spline.
    pub fn may_hold_splines(&self) -> bool {
        self.state.borrow().splines
    }

    /// Problems found so far.
    pub fn problems(&self) -> Vec<Error> {
        self.state.borrow().problems.clone()
    }

    /// Marks the root stack as checked: layers opened from now on are
    /// composition's (references, payloads) and are checked when opened.
    pub fn start_composing(&self) {
        self.state.borrow_mut().composing = true;
    }

    fn record(&self, e: Error) {
        let mut st = self.state.borrow_mut();
        if !st.problems.contains(&e) {
            st.problems.push(e);
        }
    }

    /// Checks one parsed layer (depth, arcs); records and returns a problem.
    pub fn check_layer(&self, id: &str, data: &dyn AbstractData) -> Result<(), Error> {
        if !self.state.borrow_mut().scanned.insert(id.to_string()) {
            return Ok(());
        }
        let result = self.check_layer_inner(id, data);
        if let Err(e) = &result {
            self.record(e.clone());
        }
        result
    }

    fn check_layer_inner(&self, id: &str, data: &dyn AbstractData) -> Result<(), Error> {
        let mut deepest: Option<(usize, sdf::Path)> = None;
        let mut found: Vec<(String, String)> = Vec::new();
        for path in data.spec_paths() {
            if path.is_property_path() || path.is_abs_root() {
                continue;
            }
            let prim = path.strip_all_variant_selections();
            let depth = prim.prim_element_count();
            if deepest.as_ref().is_none_or(|(d, _)| depth > *d) {
                deepest = Some((depth, prim.clone()));
            }
            for field in ["inheritPaths", "specializes"] {
                let Ok(Some(v)) = data.try_field(&path, field) else {
                    continue;
                };
                let Value::PathListOp(op) = v.as_ref() else { continue };
                for t in op
                    .explicit_items
                    .iter()
                    .chain(&op.added_items)
                    .chain(&op.prepended_items)
                    .chain(&op.appended_items)
                {
                    let abs = prim.make_absolute(t).strip_all_variant_selections();
                    found.push((prim.as_str().to_string(), abs.as_str().to_string()));
                }
            }
        }
        if let Some((depth, path)) = deepest {
            if depth > MAX_NAMESPACE_DEPTH {
                return Err(Error::msg(format!(
                    "namespace {depth} prims deep (at {}); painterly composes at most {MAX_NAMESPACE_DEPTH} levels \
                     (composition time grows with the cube of the depth)",
                    shorten(path.as_str())
                ))
                .in_file(std::path::Path::new(id)));
            }
        }
        if found.is_empty() {
            return Ok(());
        }
        {
            let mut st = self.state.borrow_mut();
            for (at, target) in found {
                st.targets.entry(at).or_default().push((target, id.to_string()));
            }
        }
        match self.find_cycle() {
            Some(cycle) => Err(Error::msg(format!(
                "inherit/specialize cycle: {} (usd-core reports it as a composition error; \
                 openusd 0.8 cannot compose it)",
                cycle.join(" -> ")
            ))
            .in_file(std::path::Path::new(id))),
            None => Ok(()),
        }
    }

    /// A cycle of inherit/specialize arcs (each path inheriting or
    /// specializing the next), if any. Such a cycle is a composition error
    /// for usd-core and endless recursion for openusd 0.8. Cycles that only
    /// form through namespace mapping are left to [`super::compose_watch`]:
    /// modelling them needs Pcp itself, and a closer model refused valid
    /// hierarchies.
    fn find_cycle(&self) -> Option<Vec<String>> {
        let st = self.state.borrow();
        let next = |x: &str| -> Vec<String> {
            st.targets
                .get(x)
                .map(|ts| ts.iter().map(|(t, _)| t.clone()).collect())
                .unwrap_or_default()
        };
        // Iterative DFS with colours over every target path.
        let mut starts: Vec<String> = st.targets.values().flatten().map(|(t, _)| t.clone()).collect();
        starts.sort();
        starts.dedup();
        let mut colour: HashMap<String, u8> = HashMap::new(); // 1 on stack, 2 done
        for s in starts {
            if colour.contains_key(&s) {
                continue;
            }
            let mut stack: Vec<(String, Vec<String>)> = vec![(s.clone(), next(&s))];
            colour.insert(s, 1);
            while let Some((node, succ)) = stack.last_mut() {
                match succ.pop() {
                    Some(n) => match colour.get(&n) {
                        Some(1) => {
                            let mut cycle: Vec<String> = stack.iter().map(|(p, _)| p.clone()).collect();
                            let from = cycle.iter().position(|p| *p == n).unwrap_or(0);
                            cycle.drain(..from);
                            cycle.push(n);
                            return Some(cycle);
                        }
                        Some(_) => {}
                        None => {
                            colour.insert(n.clone(), 1);
                            let s = next(&n);
                            stack.push((n, s));
                        }
                    },
                    None => {
                        colour.insert(node.clone(), 2);
                        stack.pop();
                    }
                }
            }
        }
        None
    }

    /// Checks raw layer bytes before openusd parses them.
    fn check_bytes(&self, resolved: &ResolvedPath, bytes: &[u8]) -> Result<(), Error> {
        let file = std::path::Path::new(resolved.to_str().unwrap_or_default());
        if !self.state.borrow().splines && may_hold_splines(bytes) {
            self.state.borrow_mut().splines = true;
        }
        if bytes.starts_with(b"#usda") {
            let (depth, at) = usda_text::max_nesting(bytes);
            if depth > MAX_TEXT_NESTING {
                let e = Error::msg(format!(
                    "brackets nested {depth} deep (line {}); painterly reads at most {MAX_TEXT_NESTING} levels",
                    usda_text::line_of(bytes, at)
                ))
                .in_file(file);
                self.record(e.clone());
                return Err(e);
            }
        }
        let composing = self.state.borrow().composing;
        // usdz packages are read entry by entry through this resolver.
        if composing && !bytes.starts_with(b"PK") {
            let id = resolved.to_str().unwrap_or_default().to_string();
            if self.state.borrow().scanned.contains(&id) {
                return Ok(());
            }
            // Unparseable bytes are openusd's to report.
            if let Ok(data) = sdf::LayerRegistry::read_bytes(AssetBuffer::Owned(bytes.to_vec()), &id) {
                self.check_layer(&id, &data)?;
            }
        }
        Ok(())
    }
}

/// Whether a layer's bytes may author a spline (USD 25.05): a crate file of
/// version 0.12 or later (the version splines need), text with `.spline`
/// in it, or bytes of neither kind. A zip (a `.usdz`) holds none itself:
/// its layers are read one by one.
fn may_hold_splines(bytes: &[u8]) -> bool {
    if bytes.starts_with(b"PXR-USDC") {
        return bytes.get(8..10).is_none_or(|v| (v[0], v[1]) >= (0, 12));
    }
    if bytes.starts_with(b"#usda") {
        return bytes.windows(7).any(|w| w == b".spline");
    }
    !bytes.starts_with(b"PK")
}

/// Opens one layer without composing it, through the guard and under
/// [`super::compose_watch`].
pub fn open_layer(path: &std::path::Path) -> Result<sdf::Layer, Error> {
    let s = path
        .to_str()
        .ok_or_else(|| Error::msg("path is not valid UTF-8").in_file(path))?;
    let guard = Guard::default();
    super::compose_watch::watched(path, || {
        let layer = sdf::Layer::open_with(guard.resolver(), s).map_err(|e| {
            guard
                .problems()
                .into_iter()
                .next()
                .unwrap_or_else(|| Error::msg(format!("cannot read USD file: {}", super::stage::with_causes(&e))))
                .in_file(path)
        })?;
        guard.check_layer(s, layer.data())?;
        Ok(layer)
    })
}

/// A long path, cut for messages.
fn shorten(p: &str) -> String {
    if p.len() <= 120 {
        p.to_string()
    } else {
        let mut cut = 100;
        while !p.is_char_boundary(cut) {
            cut -= 1;
        }
        format!("{}…", &p[..cut])
    }
}

/// A resolver (by default [`super::regular::RegularResolver`]) checking each layer's bytes
/// before openusd does.
pub struct GuardedResolver<R = super::regular::RegularResolver> {
    inner: R,
    guard: Guard,
}

impl<R: ar::Resolver> ar::Resolver for GuardedResolver<R> {
    fn create_identifier(&self, asset_path: &str, anchor: Option<&ResolvedPath>) -> String {
        self.inner.create_identifier(asset_path, anchor)
    }

    fn resolve(&self, asset_path: &str) -> Option<ResolvedPath> {
        self.inner.resolve(asset_path)
    }

    fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ResolvedPath> {
        self.inner.resolve_for_new_asset(asset_path)
    }

    fn open_asset(&self, resolved_path: &ResolvedPath) -> io::Result<Box<dyn Asset>> {
        // Before the read: a save between the two shows as a change later.
        self.guard.note_opened(resolved_path);
        let buffer = self.inner.open_asset(resolved_path)?.into_buffer()?;
        if let Err(e) = self.guard.check_bytes(resolved_path, &buffer) {
            return Err(io::Error::new(io::ErrorKind::InvalidData, e.message));
        }
        Ok(Box::new(io::Cursor::new(buffer)))
    }

    super::regular::forward_to_inner!();
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(text: &str) -> sdf::LayerData {
        sdf::LayerRegistry::read_bytes(AssetBuffer::Owned(text.as_bytes().to_vec()), "t.usda").unwrap()
    }

    #[test]
    fn only_layers_that_may_author_splines_are_flagged() {
        let crate_of = |major: u8, minor: u8| {
            let mut b = b"PXR-USDC".to_vec();
            b.extend([major, minor, 0, 0, 0, 0, 0, 0]);
            b
        };
        assert!(!may_hold_splines(&crate_of(0, 8)));
        assert!(!may_hold_splines(&crate_of(0, 11)));
        assert!(may_hold_splines(&crate_of(0, 12)));
        assert!(may_hold_splines(&crate_of(1, 0)));
        assert!(may_hold_splines(b"PXR-USDC"));
        assert!(!may_hold_splines(b"#usda 1.0\ndef \"P\" {\n    double x = 1\n}\n"));
        assert!(may_hold_splines(
            b"#usda 1.0\ndef \"P\" {\n    double x.spline = { 1: 0 }\n}\n"
        ));
        assert!(!may_hold_splines(b"PK\x03\x04"));
        assert!(may_hold_splines(b"something else"));
    }

    #[test]
    fn a_file_id_holds_the_modification_time_to_the_nanosecond() {
        // Two saves within one second, or a second apart with the
        // nanoseconds one lower, are two versions.
        use std::time::{Duration, UNIX_EPOCH};
        let dir = super::super::atomic::TempDir::new().unwrap();
        let p = dir.path().join("f.usda");
        std::fs::write(&p, "#usda 1.0\n").unwrap();
        let file = std::fs::File::options().write(true).open(&p).unwrap();
        let mut ids = Vec::new();
        for (s, ns) in [(1_700_000_000, 500), (1_700_000_000, 501), (1_700_000_001, 499)] {
            let t = std::fs::FileTimes::new().set_modified(UNIX_EPOCH + Duration::new(s, ns));
            file.set_times(t).unwrap();
            let id = FileId::of(&p).unwrap();
            assert_eq!(id.mtime_ns, i128::from(s) * 1_000_000_000 + i128::from(ns));
            ids.push(id);
        }
        assert!(ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2]);
        assert!(ids[0].same_file(&ids[2]) && ids[2].same_file(&ids[0]));
    }

    #[test]
    fn finds_inherit_cycles_and_passes_hierarchies() {
        let cyc = "#usda 1.0\nclass \"A\" (inherits = </B>)\n{\n}\nclass \"B\" (specializes = </A>)\n{\n}\n";
        let g = Guard::default();
        let e = g.check_layer("c.usda", &layer(cyc)).unwrap_err();
        assert!(e.message.contains("cycle"), "{e}");
        assert_eq!(g.problems().len(), 1);

        let own = "#usda 1.0\nclass \"A\" (inherits = </A>)\n{\n}\n";
        assert!(Guard::default().check_layer("s.usda", &layer(own)).is_err());

        // Not a cycle for usd-core: /A inherits /B, /B inherits /A's child.
        let par = "#usda 1.0\ndef \"A\" (inherits = </B>)\n{\n    def \"X\"\n    {\n    }\n}\nclass \"B\" (inherits = </A/X>)\n{\n}\n";
        Guard::default().check_layer("p.usda", &layer(par)).unwrap();

        let ok = "#usda 1.0\nclass \"Base\"\n{\n}\nclass \"Mid\" (inherits = </Base>)\n{\n}\ndef \"C\" (inherits = </Mid>)\n{\n    def \"D\" (specializes = </Base>)\n    {\n    }\n}\n";
        Guard::default().check_layer("ok.usda", &layer(ok)).unwrap();
    }

    #[test]
    fn cycles_across_layers_of_one_stack() {
        let g = Guard::default();
        g.check_layer("a.usda", &layer("#usda 1.0\nclass \"A\" (inherits = </B>)\n{\n}\n"))
            .unwrap();
        let e = g
            .check_layer("b.usda", &layer("#usda 1.0\nclass \"B\" (inherits = </A>)\n{\n}\n"))
            .unwrap_err();
        assert!(
            e.to_string().contains("/A -> /B -> /A") || e.to_string().contains("/B -> /A -> /B"),
            "{e}"
        );
    }

    #[test]
    fn namespace_depth_limit() {
        let n = MAX_NAMESPACE_DEPTH + 1;
        let text = format!("#usda 1.0\n{}{}", "def \"P\" {\n".repeat(n), "}\n".repeat(n));
        let e = Guard::default().check_layer("d.usda", &layer(&text)).unwrap_err();
        assert!(e.message.contains(&format!("{n} prims deep")), "{e}");
        let n = MAX_NAMESPACE_DEPTH;
        let text = format!("#usda 1.0\n{}{}", "def \"P\" {\n".repeat(n), "}\n".repeat(n));
        Guard::default().check_layer("d.usda", &layer(&text)).unwrap();
    }

    /// Answers every query with a value no default resolver gives, so a
    /// wrapper that stops forwarding one shows.
    struct Stub;

    impl ar::Resolver for Stub {
        fn create_identifier(&self, asset_path: &str, _anchor: Option<&ResolvedPath>) -> String {
            format!("id:{asset_path}")
        }
        fn resolve(&self, asset_path: &str) -> Option<ResolvedPath> {
            Some(ResolvedPath::new(format!("/resolved/{asset_path}")))
        }
        fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ResolvedPath> {
            Some(ResolvedPath::new(format!("/new/{asset_path}")))
        }
        fn open_asset(&self, _resolved_path: &ResolvedPath) -> io::Result<Box<dyn Asset>> {
            Err(io::Error::other("stub"))
        }
        fn get_extension<'a>(&self, asset_path: &'a str) -> &'a str {
            &asset_path[1..]
        }
        fn is_context_dependent_path(&self, asset_path: &str) -> bool {
            asset_path == "yes"
        }
        fn in_memory_identifier<'a>(&self, asset_path: &'a str) -> std::borrow::Cow<'a, str> {
            std::borrow::Cow::Owned(format!("mem:{asset_path}"))
        }
        fn get_asset_info(&self, _asset_path: &str, _resolved_path: &ResolvedPath) -> ar::AssetInfo {
            ar::AssetInfo {
                version: "7".into(),
                ..Default::default()
            }
        }
        fn get_modification_timestamp(&self, _: &str, _: &ResolvedPath) -> Option<std::time::SystemTime> {
            Some(std::time::UNIX_EPOCH + std::time::Duration::from_secs(5))
        }
        fn identity(&self) -> String {
            "stub".into()
        }
        fn cache_id(&self) -> Option<u64> {
            Some(42)
        }
    }

    #[test]
    fn guarded_resolver_forwards_every_query_to_the_inner_one() {
        // The guard only looks at bytes; openusd must see the wrapped
        // resolver's answers (a memory layer's identifiers, its cache id).
        use ar::Resolver as _;
        let r = Guard::default().resolver_over(Stub);
        let at = ResolvedPath::new("/x/a.usda");
        assert_eq!(r.create_identifier("a.usda", None), "id:a.usda");
        assert_eq!(r.resolve("a.usda").unwrap().to_str(), Some("/resolved/a.usda"));
        assert_eq!(r.resolve_for_new_asset("a.usda").unwrap().to_str(), Some("/new/a.usda"));
        assert_eq!(r.get_extension("xusda"), "usda");
        assert!(r.is_context_dependent_path("yes"));
        assert!(!r.is_context_dependent_path("no"));
        assert_eq!(r.in_memory_identifier("a.usda"), "mem:a.usda");
        assert_eq!(r.get_asset_info("a.usda", &at).version, "7");
        assert_eq!(
            r.get_modification_timestamp("a.usda", &at),
            Some(std::time::UNIX_EPOCH + std::time::Duration::from_secs(5))
        );
        assert_eq!(r.identity(), "stub");
        assert_eq!(r.cache_id(), Some(42));
    }

    #[test]
    fn text_nesting_of_exactly_the_limit_is_read() {
        // "at most 1000 levels": 1000 nested brackets pass, 1001 do not.
        let bytes = |n: usize| format!("#usda 1.0\n{}{}\n", "[".repeat(n), "]".repeat(n)).into_bytes();
        let at = ResolvedPath::new("/x/n.usda");
        let g = Guard::default();
        g.check_bytes(&at, &bytes(1000)).unwrap();
        let e = g.check_bytes(&at, &bytes(1001)).unwrap_err();
        assert!(e.message.contains("nested 1001 deep (line 2)"), "{e}");
    }

    #[test]
    fn namespace_error_names_the_first_deepest_prim_cut_to_100_bytes() {
        // /A/P/... and /B/P/... are both 257 deep; the message names the first
        // in path order, cut after 100 bytes: "/A" and 49 "/P".
        let chain = |name: &str| {
            format!(
                "def \"{name}\" {{\n{}{}}}\n",
                "def \"P\" {\n".repeat(256),
                "}\n".repeat(256)
            )
        };
        let text = format!("#usda 1.0\n{}{}", chain("A"), chain("B"));
        let e = Guard::default().check_layer("d.usda", &layer(&text)).unwrap_err();
        let at = format!("(at /A{}…)", "/P".repeat(49));
        assert!(e.message.contains(&format!("namespace 257 prims deep {at}")), "{e}");
    }

    #[test]
    fn shorten_keeps_short_paths_and_cuts_at_a_char_boundary() {
        assert_eq!(shorten("/A/B"), "/A/B");
        assert_eq!(shorten(&"a".repeat(120)), "a".repeat(120));
        // Byte 100 falls inside the first "é" (bytes 99..101): cut before it.
        let p = format!("{}{}", "a".repeat(99), "é".repeat(20));
        assert_eq!(shorten(&p), format!("{}…", "a".repeat(99)));
    }

    #[test]
    fn layers_loaded_by_composition_are_checked() {
        // The root stack is fine; the referenced layer is 257 deep. It is
        // loaded only while composing and must be refused then.
        let dir = crate::test_dir::ScratchDir::new("guard-ref");
        let deep = format!(
            "#usda 1.0\n(\n    defaultPrim = \"P\"\n)\n{}{}",
            "def \"P\" {\n".repeat(257),
            "}\n".repeat(257)
        );
        std::fs::write(dir.join("ref.usda"), deep).unwrap();
        let root = dir.join("root.usda");
        std::fs::write(
            &root,
            "#usda 1.0\ndef \"R\" (\n    references = @./ref.usda@\n)\n{\n}\n",
        )
        .unwrap();
        let result = super::super::stage::StageReader::open(&root);
        let e = result.err().expect("a 257-deep referenced layer is refused");
        assert!(e.message.contains("namespace 257 prims deep"), "{e}");
        assert!(e.to_string().contains("ref.usda"), "{e}");
    }
}
