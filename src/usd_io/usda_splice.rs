//! In-place edits of `.usda` text that change only what they edit.
//!
//! openusd 0.8 cannot round-trip every construct usd-core writes (measured
//! here): its parser drops the prepended targets of a relationship that also
//! has appended ones and reads a spline's default (held) pre-extrapolation
//! as a block, and its `TextWriter` writes `prepend inheritPaths` (usd-core
//! refuses the file), drops spline knots' tangents and per-knot
//! interpolation, and reformats every number. So an edit layer or an
//! `--in-place` file is never re-serialised: the statements painterly
//! authored are spliced into the original text and every other byte stays
//! as it was (comments and formatting included).
//!
//! The splice covers what the authoring commands author: prim specs
//! (specifier, type name) and attribute default values. What goes into the
//! text is derived from the edited layer's own data (what openusd authored),
//! and the caller checks the result by parsing it again (see
//! [`super::edit`]).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write;
use std::ops::Range;

use openusd::sdf::{self, AbstractData, Specifier, Value, Variability};

use super::usda_text::{line_of, unquote, Kind, Lexer, Token};

/// A prim block in the text.
#[derive(Debug)]
struct PrimBlock {
    path: String,
    /// From the specifier keyword to the end of the name string.
    header: Range<usize>,
    /// Byte offsets of `{` and the matching `}`.
    open: usize,
    close: usize,
    props: Vec<Prop>,
    children: Vec<PrimBlock>,
}

/// A property statement in a prim body.
#[derive(Debug)]
struct Prop {
    name: String,
    /// `connect`, `timeSamples`, `spline`, ... for `name.suffix` statements.
    suffix: Option<String>,
    /// From the first token to the end of the value (or the name).
    head: Range<usize>,
    /// End of the statement, metadata included.
    end: usize,
}

struct Parser<'a> {
    text: &'a str,
    toks: Vec<Token>,
    i: usize,
}

type PResult<T> = Result<T, String>;

impl<'a> Parser<'a> {
    fn new(text: &'a str) -> PResult<Self> {
        let toks = Lexer::new(text.as_bytes())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| format!("line {}: {}", line_of(text.as_bytes(), e.offset), e.message))?;
        Ok(Parser { text, toks, i: 0 })
    }

    fn peek(&self) -> Option<&Token> {
        self.toks.get(self.i)
    }

    fn src(&self, t: &Token) -> &'a str {
        &self.text[t.span.clone()]
    }

    fn is_punct(&self, c: u8) -> bool {
        self.peek().is_some_and(|t| t.kind == Kind::Punct(c))
    }

    fn is_ident(&self, words: &[&str]) -> bool {
        self.peek()
            .is_some_and(|t| t.kind == Kind::Ident && words.contains(&self.src(t)))
    }

    fn unexpected(&self, what: &str) -> String {
        match self.peek() {
            Some(t) => format!(
                "line {}: expected {what}, found {:?}",
                line_of(self.text.as_bytes(), t.span.start),
                self.src(t)
            ),
            None => format!("expected {what} at the end of the file"),
        }
    }

    fn expect_punct(&mut self, c: u8) -> PResult<usize> {
        if self.is_punct(c) {
            self.i += 1;
            Ok(self.toks[self.i - 1].span.start)
        } else {
            Err(self.unexpected(&format!("'{}'", c as char)))
        }
    }

    /// Skips a bracketed group starting at the current `(`, `[` or `{`;
    /// returns the byte offset after its closing bracket.
    fn skip_group(&mut self) -> PResult<usize> {
        let mut depth = 0usize;
        while let Some(t) = self.toks.get(self.i) {
            self.i += 1;
            match t.kind {
                Kind::Punct(b'(' | b'[' | b'{') => depth += 1,
                Kind::Punct(b')' | b']' | b'}') => {
                    depth = depth.saturating_sub(1);
                    if depth == 0 {
                        return Ok(t.span.end);
                    }
                }
                _ => {}
            }
            if depth == 0 {
                return Err(self.unexpected("a bracket"));
            }
        }
        Err("unbalanced brackets".into())
    }

    fn layer(&mut self) -> PResult<Vec<PrimBlock>> {
        if self.is_punct(b'(') {
            self.skip_group()?;
        }
        let mut prims = Vec::new();
        while self.peek().is_some() {
            if self.is_ident(&["def", "over", "class"]) {
                prims.push(self.prim("")?);
            } else if self.is_ident(&["reorder"]) {
                self.i += 1;
                self.statement_rest()?;
            } else if self.is_punct(b';') {
                self.i += 1;
            } else {
                return Err(self.unexpected("a prim"));
            }
        }
        Ok(prims)
    }

    /// `def Type "name" (metadata) { body }`.
    fn prim(&mut self, parent: &str) -> PResult<PrimBlock> {
        let start = self.toks[self.i].span.start;
        self.i += 1;
        while self.peek().is_some_and(|t| t.kind == Kind::Ident) {
            self.i += 1;
        }
        let name_tok = match self.peek() {
            Some(t) if t.kind == Kind::Str => t.clone(),
            _ => return Err(self.unexpected("a prim name")),
        };
        self.i += 1;
        let name = unquote(self.src(&name_tok));
        let path = format!("{parent}/{name}");
        if self.is_punct(b'(') {
            self.skip_group()?;
        }
        let open = self.expect_punct(b'{')?;
        let mut block = PrimBlock {
            path,
            header: start..name_tok.span.end,
            open,
            close: 0,
            props: Vec::new(),
            children: Vec::new(),
        };
        loop {
            match self.peek() {
                None => return Err(format!("prim {} is not closed", block.path)),
                Some(t) if t.kind == Kind::Punct(b'}') => {
                    block.close = t.span.start;
                    self.i += 1;
                    return Ok(block);
                }
                Some(t) if t.kind == Kind::Punct(b';') => self.i += 1,
                Some(_) if self.is_ident(&["def", "over", "class"]) => {
                    let child = self.prim(&block.path)?;
                    block.children.push(child);
                }
                Some(_) if self.is_ident(&["variantSet"]) => {
                    // Variant contents are not this prim's namespace children.
                    self.i += 1;
                    match self.peek() {
                        Some(t) if t.kind == Kind::Str => self.i += 1,
                        _ => return Err(self.unexpected("a variant set name")),
                    }
                    self.expect_punct(b'=')?;
                    if !self.is_punct(b'{') {
                        return Err(self.unexpected("'{'"));
                    }
                    self.skip_group()?;
                }
                Some(_) if self.is_ident(&["reorder"]) => {
                    self.i += 1;
                    self.statement_rest()?;
                }
                Some(_) => {
                    let p = self.property()?;
                    block.props.push(p);
                }
            }
        }
    }

    /// The rest of `reorder x = [...]`.
    fn statement_rest(&mut self) -> PResult<()> {
        if !self.is_ident(&["nameChildren", "properties", "rootPrims"]) {
            return Err(self.unexpected("nameChildren or properties"));
        }
        self.i += 1;
        self.expect_punct(b'=')?;
        self.value()?;
        Ok(())
    }

    /// One value after `=`; returns the byte offset after it.
    fn value(&mut self) -> PResult<usize> {
        match self.peek() {
            Some(t) if matches!(t.kind, Kind::Punct(b'(' | b'[' | b'{')) => self.skip_group(),
            Some(t) if matches!(t.kind, Kind::Punct(b'-' | b'+')) => {
                self.i += 1;
                self.atom()
            }
            _ => self.atom(),
        }
    }

    fn atom(&mut self) -> PResult<usize> {
        match self.peek() {
            Some(t)
                if matches!(
                    t.kind,
                    Kind::Ident | Kind::Str | Kind::Num | Kind::PathRef | Kind::Asset
                ) =>
            {
                let end = t.span.end;
                self.i += 1;
                // An asset followed by a prim path (`@a.usda@</P>`).
                if self.peek().is_some_and(|n| n.kind == Kind::PathRef) && self.toks[self.i - 1].kind == Kind::Asset {
                    self.i += 1;
                    return Ok(self.toks[self.i - 1].span.end);
                }
                Ok(end)
            }
            _ => Err(self.unexpected("a value")),
        }
    }

    /// `[prepend|…] [custom] [uniform|varying|config] (rel | type[[]]) name[.suffix] [= value] [(metadata)]`.
    fn property(&mut self) -> PResult<Prop> {
        let start = self.toks[self.i].span.start;
        if self.is_ident(&["prepend", "append", "add", "delete"]) {
            self.i += 1;
        }
        if self.is_ident(&["custom"]) {
            self.i += 1;
        }
        if self.is_ident(&["uniform", "varying", "config"]) {
            self.i += 1;
        }
        if self.is_ident(&["rel"]) {
            self.i += 1;
        } else {
            match self.peek() {
                Some(t) if t.kind == Kind::Ident => self.i += 1,
                _ => return Err(self.unexpected("a property")),
            }
            if self.is_punct(b'[') {
                self.i += 1;
                self.expect_punct(b']')?;
            }
        }
        let name_tok = match self.peek() {
            Some(t) if t.kind == Kind::Ident => t.clone(),
            _ => return Err(self.unexpected("a property name")),
        };
        self.i += 1;
        let mut head_end = name_tok.span.end;
        let mut suffix = None;
        if self.is_punct(b'.') {
            self.i += 1;
            match self.peek() {
                Some(t) if t.kind == Kind::Ident => {
                    suffix = Some(self.src(t).to_string());
                    head_end = t.span.end;
                    self.i += 1;
                }
                _ => return Err(self.unexpected("connect, timeSamples or spline")),
            }
        }
        if self.is_punct(b'=') {
            self.i += 1;
            head_end = self.value()?;
        }
        let mut end = head_end;
        if self.is_punct(b'(') {
            end = self.skip_group()?;
        }
        Ok(Prop {
            name: self.src(&name_tok).to_string(),
            suffix,
            head: start..head_end,
            end,
        })
    }
}

fn index<'b>(blocks: &'b [PrimBlock], out: &mut HashMap<String, &'b PrimBlock>) {
    for b in blocks {
        out.entry(b.path.clone()).or_insert(b);
        index(&b.children, out);
    }
}

/// Leading whitespace of the line holding byte `at`.
fn indent_at(text: &str, at: usize) -> String {
    let line_start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    text[line_start..at]
        .chars()
        .take_while(|c| *c == ' ' || *c == '\t')
        .collect()
}

/// Formats a float the way usda reads it back to the same value.
fn fmt_f64(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.into()
    } else if x == 0.0 || (1e-5..1e16).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn fmt_f32(x: f32) -> String {
    if x.is_nan() || x.is_infinite() {
        fmt_f64(x as f64)
    } else if x == 0.0 || (1e-5..1e16).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn quote(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

fn list<T>(items: &[T], f: impl Fn(&T) -> String) -> String {
    let mut s = String::with_capacity(items.len() * 8 + 2);
    s.push('[');
    for (i, x) in items.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        s.push_str(&f(x));
    }
    s.push(']');
    s
}

/// A default value in usda syntax, for the kinds painterly authors.
pub fn format_value(v: &Value) -> Option<String> {
    let v3f = |p: &openusd::gf::Vec3f| format!("({}, {}, {})", fmt_f32(p.x), fmt_f32(p.y), fmt_f32(p.z));
    let v3d = |p: &openusd::gf::Vec3d| format!("({}, {}, {})", fmt_f64(p.x), fmt_f64(p.y), fmt_f64(p.z));
    let v3i = |p: &openusd::gf::Vec3i| format!("({}, {}, {})", p.x, p.y, p.z);
    Some(match v {
        Value::Bool(b) => if *b { "1" } else { "0" }.into(),
        Value::Int(x) => x.to_string(),
        Value::Int64(x) => x.to_string(),
        Value::Uint(x) => x.to_string(),
        Value::Float(x) => fmt_f32(*x),
        Value::Double(x) => fmt_f64(*x),
        Value::String(s) => quote(s),
        Value::Token(t) => quote(t.as_str()),
        Value::FloatVec(a) => list(a, |x| fmt_f32(*x)),
        Value::DoubleVec(a) => list(a, |x| fmt_f64(*x)),
        Value::IntVec(a) => list(a, |x| x.to_string()),
        Value::TokenVec(a) => list(a, |t| quote(t.as_str())),
        Value::StringVec(a) => list(a, |s| quote(s)),
        Value::Vec3f(p) => v3f(p),
        Value::Vec3d(p) => v3d(p),
        Value::Vec3fVec(a) => list(a, v3f),
        Value::Vec3dVec(a) => list(a, v3d),
        Value::Vec3iVec(a) => list(a, v3i),
        // A blocked default (`key --replace` clears what it does not set).
        Value::ValueBlock => "None".into(),
        _ => return None,
    })
}

fn field<'d>(data: &'d dyn AbstractData, path: &sdf::Path, name: &str) -> Option<std::borrow::Cow<'d, Value>> {
    data.try_field(path, name).ok().flatten()
}

/// `def Type "name"` for a prim spec of `data`.
fn prim_header(data: &dyn AbstractData, path: &sdf::Path) -> PResult<String> {
    let spec = match field(data, path, "specifier").as_deref() {
        Some(Value::Specifier(Specifier::Def)) => "def",
        Some(Value::Specifier(Specifier::Class)) => "class",
        _ => "over",
    };
    let ty = match field(data, path, "typeName").as_deref() {
        Some(Value::Token(t)) if !t.as_str().is_empty() => format!("{} ", t.as_str()),
        _ => String::new(),
    };
    let name = path.name().ok_or_else(|| format!("{path} has no name"))?;
    Ok(format!("{spec} {ty}{}", quote(name)))
}

/// A new prim block is written from its header alone: any other prim field
/// (metadata) would be lost. An existing prim keeps its metadata as written,
/// since only its header is replaced.
fn check_prim_fields(data: &dyn AbstractData, path: &sdf::Path) -> PResult<()> {
    for f in data.list_fields(path).unwrap_or_default() {
        if !["specifier", "typeName", "primChildren", "propertyChildren"].contains(&f.as_str()) {
            return Err(format!("{path}: cannot write the prim field {f}"));
        }
    }
    Ok(())
}

/// `[custom] [uniform] type name = value` for an attribute spec of `data`.
fn attr_decl(data: &dyn AbstractData, path: &sdf::Path, name: &str) -> PResult<String> {
    let mut s = String::new();
    if let Some(Value::Bool(true)) = field(data, path, "custom").as_deref() {
        s.push_str("custom ");
    }
    match field(data, path, "variability").as_deref() {
        Some(Value::Variability(Variability::Uniform)) => s.push_str("uniform "),
        Some(Value::Variability(Variability::Varying)) | None => {}
        Some(other) => return Err(format!("{path}: cannot write variability {other:?}")),
    }
    match field(data, path, "typeName").as_deref() {
        Some(Value::Token(t)) => s.push_str(t.as_str()),
        _ => return Err(format!("{path} has no type")),
    }
    let _ = write!(s, " {name}");
    if let Some(v) = field(data, path, "default") {
        let text =
            format_value(&v).ok_or_else(|| format!("{path}: cannot write a {} value", super::values::kind_name(&v)))?;
        let _ = write!(s, " = {text}");
    }
    Ok(s)
}

/// Fields of a property statement this module rewrites; others must be in
/// the text already (metadata kept as written).
const ATTR_FIELDS: [&str; 4] = ["typeName", "custom", "variability", "default"];

/// Splices the prim specs `prims` and attribute specs `attrs` (prim path,
/// attribute name) of `data` into `text`: missing specs are inserted, the
/// headers of existing prims in `defined` and the declarations of existing
/// attributes are rewritten; every other byte of `text` is kept. `prims`
/// must list every prim spec that may be new in `data` (ancestors of new
/// prims included).
pub fn splice(
    text: &str,
    data: &dyn AbstractData,
    prims: &[String],
    defined: &[String],
    attrs: &[(String, String)],
) -> PResult<String> {
    let mut p = Parser::new(text)?;
    let roots = p.layer()?;
    let mut blocks = HashMap::new();
    index(&roots, &mut blocks);

    let sdf_path = |s: &str| sdf::Path::new(s).map_err(|e| format!("{s}: {e}"));
    let mut edits: Vec<(Range<usize>, String)> = Vec::new();
    // New prims by parent path, in order; attributes by prim path.
    let mut new_children: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut attrs_of: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for (prim, name) in attrs {
        let list = attrs_of.entry(prim.clone()).or_default();
        if !list.contains(name) {
            list.push(name.clone());
        }
    }
    for path in prims {
        let sp = sdf_path(path)?;
        match blocks.get(path.as_str()) {
            Some(b) => {
                if defined.contains(path) {
                    let header = prim_header(data, &sp)?;
                    if text[b.header.clone()] != header {
                        edits.push((b.header.clone(), header));
                    }
                }
            }
            None => {
                let parent = match path.rsplit_once('/') {
                    Some(("", _)) => "/".to_string(),
                    Some((p, _)) => p.to_string(),
                    None => return Err(format!("{path} is not an absolute prim path")),
                };
                let kids = new_children.entry(parent).or_default();
                if !kids.contains(path) {
                    kids.push(path.clone());
                }
            }
        }
    }
    for prim in attrs_of.keys() {
        if !blocks.contains_key(prim.as_str()) && !prims.contains(prim) {
            return Err(format!("{prim} has no spec in the text and was not authored"));
        }
    }

    // Renders a new prim (and its new children) as a block.
    fn render(
        path: &str,
        indent: &str,
        data: &dyn AbstractData,
        new_children: &BTreeMap<String, Vec<String>>,
        attrs_of: &BTreeMap<String, Vec<String>>,
        out: &mut String,
    ) -> PResult<()> {
        let sp = sdf::Path::new(path).map_err(|e| format!("{path}: {e}"))?;
        check_prim_fields(data, &sp)?;
        let _ = writeln!(out, "{indent}{}", prim_header(data, &sp)?);
        let _ = writeln!(out, "{indent}{{");
        for name in attrs_of.get(path).into_iter().flatten() {
            let ap = sp
                .append_property(name.as_str())
                .map_err(|e| format!("{path}.{name}: {e}"))?;
            check_attr_fields(data, &ap)?;
            let _ = writeln!(out, "{indent}    {}", attr_decl(data, &ap, name)?);
        }
        for (k, child) in new_children.get(path).into_iter().flatten().enumerate() {
            if k > 0 || attrs_of.get(path).is_some_and(|a| !a.is_empty()) {
                out.push('\n');
            }
            render(child, &format!("{indent}    "), data, new_children, attrs_of, out)?;
        }
        let _ = writeln!(out, "{indent}}}");
        Ok(())
    }

    // New prims under existing parents (or at the root).
    for (parent, kids) in &new_children {
        let (at, indent, tail) = if parent == "/" {
            (text.len(), String::new(), String::new())
        } else if let Some(b) = blocks.get(parent.as_str()) {
            let indent = format!("{}    ", indent_at(text, b.header.start));
            let line_start = text[..b.close].rfind('\n').map_or(0, |i| i + 1);
            if text[line_start..b.close].trim().is_empty() {
                (line_start, indent, String::new())
            } else {
                (b.close, indent, indent_at(text, b.header.start))
            }
        } else if prims.contains(parent) {
            continue; // rendered inside its new parent
        } else {
            return Err(format!("the parent of {} has no spec in the text", kids[0]));
        };
        let mut block = String::new();
        if parent == "/" && !text.ends_with('\n') && !text.is_empty() {
            block.push('\n');
        }
        for kid in kids {
            block.push('\n');
            render(kid, &indent, data, &new_children, &attrs_of, &mut block)?;
        }
        if !tail.is_empty() {
            block.insert(0, '\n');
            block.push_str(&tail);
        }
        edits.push((at..at, block));
    }

    // Attributes of existing prims.
    for (prim, names) in &attrs_of {
        let Some(b) = blocks.get(prim.as_str()) else { continue };
        let sp = sdf_path(prim)?;
        let indent = format!("{}    ", indent_at(text, b.header.start));
        let mut inserted = String::new();
        for name in names {
            let ap = sp
                .append_property(name.as_str())
                .map_err(|e| format!("{prim}.{name}: {e}"))?;
            let decl = attr_decl(data, &ap, name)?;
            match b.props.iter().find(|p| p.name == *name && p.suffix.is_none()) {
                Some(p) => edits.push((p.head.clone(), decl)),
                None => {
                    check_attr_fields(data, &ap)?;
                    let _ = write!(inserted, "\n{indent}{decl}");
                }
            }
        }
        if inserted.is_empty() {
            continue;
        }
        // After the last property statement (and a comment ending its line),
        // or right after `{`.
        let mut at = b.props.iter().map(|p| p.end).max().unwrap_or(b.open + 1);
        let rest = &text[at..];
        let spaces = rest.len() - rest.trim_start_matches([' ', '\t']).len();
        if rest[spaces..].starts_with('#') {
            at += spaces + rest[spaces..].find('\n').unwrap_or(rest.len() - spaces);
        } else if rest[spaces..].starts_with('}') {
            inserted.push('\n');
            inserted.push_str(&indent_at(text, b.header.start));
        }
        edits.push((at..at, inserted));
    }

    edits.sort_by_key(|(r, _)| (r.start, r.end));
    for w in edits.windows(2) {
        if w[0].0.end > w[1].0.start {
            return Err("overlapping edits".into());
        }
    }
    let mut out = String::with_capacity(text.len() + edits.iter().map(|(_, s)| s.len()).sum::<usize>());
    let mut pos = 0;
    for (r, s) in &edits {
        out.push_str(&text[pos..r.start]);
        out.push_str(s);
        pos = r.end;
    }
    out.push_str(&text[pos..]);
    Ok(out)
}

/// Each prim's property names in the order usd-core reads them from `text`:
/// the order of their first statements, a declaration or a suffixed one
/// (`name.connect`, `.timeSamples`, `.spline`) alike. openusd 0.8 differs: it
/// lists a property that has only suffixed statements after all declared
/// ones, so its `propertyChildren` cannot tell whether a splice kept them.
pub fn property_orders(text: &str) -> PResult<HashMap<String, Vec<String>>> {
    let mut p = Parser::new(text)?;
    let roots = p.layer()?;
    let mut blocks = HashMap::new();
    index(&roots, &mut blocks);
    Ok(blocks
        .into_iter()
        .map(|(path, b)| {
            let mut names: Vec<String> = Vec::new();
            for prop in &b.props {
                if !names.contains(&prop.name) {
                    names.push(prop.name.clone());
                }
            }
            (path, names)
        })
        .collect())
}

fn check_attr_fields(data: &dyn AbstractData, path: &sdf::Path) -> PResult<()> {
    for f in data.list_fields(path).unwrap_or_default() {
        if !ATTR_FIELDS.contains(&f.as_str()) {
            return Err(format!("{path}: cannot write the attribute field {f}"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> sdf::LayerData {
        sdf::LayerRegistry::read_bytes(openusd::ar::AssetBuffer::Owned(text.as_bytes().to_vec()), "t.usda").unwrap()
    }

    #[test]
    fn scans_usd_core_text() {
        let text = r#"#usda 1.0
(
    doc = "x { y"
)

def Xform "A" (
    prepend inherits = </_cls>
    variants = {
        string v = "a"
    }
    prepend variantSets = "v"
)
{
    custom rel r
    prepend rel r = </A>
    double s.spline = {
        1: 2; post held,
    }
    float3[] extent = [(0, 0, 0), (1, 1, 1)] (
        interpolation = "constant"
    )
    float x.timeSamples = {
        1: -inf,
    }
    variantSet "v" = {
        "a" {
            def "InVariant"
            {
            }
        }
    }

    def Scope "B"
    {
    }
}
"#;
        let mut p = Parser::new(text).unwrap();
        let roots = p.layer().unwrap();
        assert_eq!(roots.len(), 1);
        let a = &roots[0];
        assert_eq!(a.path, "/A");
        assert_eq!(&text[a.header.clone()], "def Xform \"A\"");
        let names: Vec<(&str, Option<&str>)> = a.props.iter().map(|p| (p.name.as_str(), p.suffix.as_deref())).collect();
        assert_eq!(
            names,
            [
                ("r", None),
                ("r", None),
                ("s", Some("spline")),
                ("extent", None),
                ("x", Some("timeSamples"))
            ]
        );
        assert_eq!(a.children.len(), 1);
        assert_eq!(a.children[0].path, "/A/B");
        assert!(text[a.props[3].head.clone()].ends_with("(1, 1, 1)]"));
    }

    #[test]
    fn scans_reorders_separators_signs_and_assets() {
        let text = r#"#usda 1.0
(
    defaultPrim = "A"
)

reorder rootPrims = ["C", "A"]
;
class "C"
{
}

def Xform "A" (
    kind = "component"
)
{
    reorder nameChildren = ["B", "X"]
    reorder properties = ["d", "i"]
    ;
    double d = -1.5
    int i = +3 (
        doc = "signed"
    )
    asset a = @a.usda@</P>
    asset b = @b.usda@
    custom uniform token[] t = ["x", "y"]
    rel r
    float2 f.connect = </A.g>

    over "B"
    {
        ;
    }
}
"#;
        let mut p = Parser::new(text).unwrap();
        let roots = p.layer().unwrap();
        let paths: Vec<&str> = roots.iter().map(|b| b.path.as_str()).collect();
        assert_eq!(paths, ["/C", "/A"]);
        assert_eq!(&text[roots[0].header.clone()], "class \"C\"");
        let a = &roots[1];
        assert_eq!(&text[a.header.clone()], "def Xform \"A\"");
        let heads: Vec<&str> = a.props.iter().map(|p| &text[p.head.clone()]).collect();
        assert_eq!(
            heads,
            [
                "double d = -1.5",
                "int i = +3",
                "asset a = @a.usda@</P>",
                "asset b = @b.usda@",
                "custom uniform token[] t = [\"x\", \"y\"]",
                "rel r",
                "float2 f.connect = </A.g>",
            ]
        );
        let names: Vec<(&str, Option<&str>)> = a.props.iter().map(|p| (p.name.as_str(), p.suffix.as_deref())).collect();
        assert_eq!(
            names,
            [
                ("d", None),
                ("i", None),
                ("a", None),
                ("b", None),
                ("t", None),
                ("r", None),
                ("f", Some("connect"))
            ]
        );
        // The statement ends after its metadata.
        assert!(text[a.props[1].head.start..a.props[1].end].ends_with("doc = \"signed\"\n    )"));
        assert_eq!(a.props[0].end, a.props[0].head.end);
        assert_eq!(a.children.len(), 1);
        assert_eq!(a.children[0].path, "/A/B");
        assert_eq!(&text[a.children[0].header.clone()], "over \"B\"");
        assert_eq!(&text[a.open..=a.open], "{");
        assert_eq!(&text[a.close..], "}\n");
    }

    #[test]
    fn malformed_text_is_refused_with_what_was_expected() {
        let err = |body: &str| {
            let text = format!("#usda 1.0\n\ndef \"A\"\n{{\n{body}\n}}\n");
            Parser::new(&text).and_then(|mut p| p.layer()).map(|_| ()).unwrap_err()
        };
        assert_eq!(
            err("    def Xform\n    {\n    }"),
            "line 6: expected a prim name, found \"{\""
        );
        assert_eq!(
            err("    variantSet v = {\n    }"),
            "line 5: expected a variant set name, found \"v\""
        );
        assert_eq!(
            err("    reorder children = []"),
            "line 5: expected nameChildren or properties, found \"children\""
        );
        assert_eq!(err("    float x = ;"), "line 5: expected a value, found \";\"");
        assert_eq!(
            err("    uniform \"s\" x"),
            "line 5: expected a property, found \"\\\"s\\\"\""
        );
        assert_eq!(err("    float = 1"), "line 5: expected a property name, found \"=\"");
        assert_eq!(
            err("    float x.\"s\" = 1"),
            "line 5: expected connect, timeSamples or spline, found \"\\\"s\\\"\""
        );
        assert_eq!(err("    float x = -"), "line 6: expected a value, found \"}\"");
        let text = "#usda 1.0\ndef \"A\"\n{\n    float x =";
        assert_eq!(
            Parser::new(text).and_then(|mut p| p.layer()).map(|_| ()).unwrap_err(),
            "expected a value at the end of the file"
        );
    }

    #[test]
    fn formats_every_kind_it_authors_so_openusd_reads_it_back() {
        use openusd::gf::{Vec3d, Vec3f, Vec3i};
        let cases = [
            ("bool", Value::Bool(true), "1"),
            ("int", Value::Int(-7), "-7"),
            ("int64", Value::Int64(-8_000_000_000), "-8000000000"),
            ("uint", Value::Uint(4_000_000_000), "4000000000"),
            ("float", Value::Float(0.25), "0.25"),
            ("double", Value::Double(-1e-9), "-1e-9"),
            (
                "string",
                Value::String("a \"q\" \\ b\nc".into()),
                "\"a \\\"q\\\" \\\\ b\\nc\"",
            ),
            ("token", Value::Token("tok".into()), "\"tok\""),
            ("float[]", Value::FloatVec(vec![1.5, 2e20]), "[1.5, 2e20]"),
            ("double[]", Value::DoubleVec(vec![0.0, 123456.5]), "[0, 123456.5]"),
            ("int[]", Value::IntVec(vec![3, -4]), "[3, -4]"),
            (
                "token[]",
                Value::TokenVec(vec!["a".into(), "b".into()]),
                "[\"a\", \"b\"]",
            ),
            ("string[]", Value::StringVec(vec!["s".into()]), "[\"s\"]"),
            (
                "float3",
                Value::Vec3f(Vec3f {
                    x: 1.0,
                    y: -2.0,
                    z: 0.5,
                }),
                "(1, -2, 0.5)",
            ),
            ("double3", Value::Vec3d(Vec3d { x: 0.1, y: 0.0, z: 3.0 }), "(0.1, 0, 3)"),
            (
                "point3f[]",
                Value::Vec3fVec(vec![Vec3f { x: 1.0, y: 2.0, z: 3.0 }]),
                "[(1, 2, 3)]",
            ),
            (
                "double3[]",
                Value::Vec3dVec(vec![Vec3d { x: 4.0, y: 5.0, z: 6.5 }]),
                "[(4, 5, 6.5)]",
            ),
            (
                "int3[]",
                Value::Vec3iVec(vec![Vec3i { x: 1, y: -2, z: 3 }]),
                "[(1, -2, 3)]",
            ),
            ("point3f[]", Value::ValueBlock, "None"),
        ];
        for (ty, value, want) in &cases {
            assert_eq!(format_value(value).as_deref(), Some(*want), "{ty}");
            let text = format!("#usda 1.0\ndef \"A\"\n{{\n    {ty} v = {want}\n}}\n");
            let back = parse(&text);
            let got = back.get_field(&sdf::Path::new("/A.v").unwrap(), "default").unwrap();
            assert_eq!(*got, *value, "{ty} read back from {want}");
        }
        // Non-finite and tiny or huge magnitudes, f64 and f32.
        assert_eq!(fmt_f64(f64::NAN), "nan");
        assert_eq!(fmt_f64(f64::INFINITY), "inf");
        assert_eq!(fmt_f64(f64::NEG_INFINITY), "-inf");
        assert_eq!(fmt_f64(0.0), "0");
        assert_eq!(fmt_f64(1e-5), "0.00001");
        assert_eq!(fmt_f64(3e-6), "3e-6");
        assert_eq!(fmt_f64(-2e16), "-2e16");
        assert_eq!(fmt_f32(f32::NAN), "nan");
        assert_eq!(fmt_f32(f32::NEG_INFINITY), "-inf");
        assert_eq!(fmt_f32(f32::INFINITY), "inf");
        assert_eq!(fmt_f32(-4e-6), "-4e-6");
    }

    #[test]
    fn headers_name_the_specifier_and_a_type_only_when_there_is_one() {
        let mut data = sdf::Data::new();
        for (p, spec, ty) in [
            ("/C", Specifier::Class, Some("Xform")),
            ("/D", Specifier::Def, Some("")),
            ("/O", Specifier::Over, None),
        ] {
            let s = data.create_spec(sdf::Path::new(p).unwrap(), sdf::SpecType::Prim);
            s.add("specifier", Value::Specifier(spec));
            if let Some(ty) = ty {
                s.add("typeName", Value::Token(ty.into()));
            }
        }
        let header = |p: &str| prim_header(&data, &sdf::Path::new(p).unwrap()).unwrap();
        assert_eq!(header("/C"), "class Xform \"C\"");
        assert_eq!(header("/D"), "def \"D\"");
        assert_eq!(header("/O"), "over \"O\"");
    }

    #[test]
    fn an_existing_prim_keeps_its_metadata_a_new_one_cannot_have_any() {
        let text = "#usda 1.0\ndef PainterlyPoseKey \"K\" (\n    doc = \"d\"\n)\n{\n}\n";
        let mut data = parse(text);
        let k = sdf::Path::new("/K").unwrap();
        data.set_field(&k, "typeName", Value::Token("PainterlyTimeKey".into()));
        // Only the header is replaced; the metadata stays as written.
        let out = splice(text, &data, &["/K".into()], &["/K".into()], &[]).unwrap();
        assert_eq!(out, text.replace("PainterlyPoseKey", "PainterlyTimeKey"));
        // A new prim is written from its header alone.
        let n = sdf::Path::new("/N").unwrap();
        data.create_spec(n.clone(), sdf::SpecType::Prim);
        data.set_field(&n, "specifier", Value::Specifier(Specifier::Def));
        data.set_field(&n, "documentation", Value::String("d".into()));
        assert_eq!(
            splice(text, &data, &["/N".into()], &["/N".into()], &[]),
            Err("/N: cannot write the prim field documentation".to_string())
        );
    }

    #[test]
    fn property_order_is_first_statements_order_suffixed_ones_included() {
        let text = "#usda 1.0\ndef \"A\"\n{\n    float c.connect = </A.x>\n    float x = 1\n    float c = 2\n    double s.spline = {\n        1: 2,\n    }\n\n    def \"B\"\n    {\n        rel r\n    }\n}\n";
        let orders = property_orders(text).unwrap();
        assert_eq!(orders["/A"], ["c", "x", "s"]);
        assert_eq!(orders["/A/B"], ["r"]);
    }

    #[test]
    fn new_children_take_the_indent_of_their_parent() {
        // Tabs before the parent's header: a new child is indented one
        // level (four spaces) deeper than that.
        let text = "#usda 1.0\ndef \"A\"\n{\n\tdef \"B\"\n\t{\n\t}\n}\n";
        let mut data = sdf::Data::new();
        for p in ["/A", "/A/B", "/A/B/K"] {
            let s = data.create_spec(sdf::Path::new(p).unwrap(), sdf::SpecType::Prim);
            s.add("specifier", Value::Specifier(Specifier::Def));
        }
        let out = splice(text, &data, &["/A/B/K".into()], &[], &[]).unwrap();
        assert_eq!(
            out,
            "#usda 1.0\ndef \"A\"\n{\n\tdef \"B\"\n\t{\n\n\t    def \"K\"\n\t    {\n\t    }\n\t}\n}\n"
        );
        assert_eq!(indent_at("x\n  \ty = 1", 6), "  \t");
        assert_eq!(indent_at("  top", 2), "  ");
    }

    #[test]
    fn splices_new_and_existing_specs() {
        let text =
            "#usda 1.0\n# a comment kept\ndef \"A\"\n{\n    float x = 1 # one\n\n    def \"B\"\n    {\n    }\n}\n";
        let mut data = sdf::Data::new();
        for (p, spec) in [("/A", "def"), ("/A/B", "def"), ("/A/B/K", "def"), ("/N", "over")] {
            let s = data.create_spec(sdf::Path::new(p).unwrap(), sdf::SpecType::Prim);
            s.add(
                "specifier",
                Value::Specifier(if spec == "def" { Specifier::Def } else { Specifier::Over }),
            );
        }
        data.set_field(
            &sdf::Path::new("/A/B/K").unwrap(),
            "typeName",
            Value::Token("PainterlyPoseKey".into()),
        );
        for (p, ty, v) in [
            ("/A.x", "float", Value::Float(2.5)),
            ("/A.y", "float[]", Value::FloatVec(vec![0.1, -3e-7, 1e20])),
            ("/A/B/K.time", "double", Value::Double(40.0)),
        ] {
            let s = data.create_spec(sdf::Path::new(p).unwrap(), sdf::SpecType::Attribute);
            s.add("typeName", Value::Token(ty.into()));
            s.add("custom", Value::Bool(false));
            s.add("variability", Value::Variability(Variability::Uniform));
            s.add("default", v);
        }
        let out = splice(
            text,
            &data,
            &["/A/B".into(), "/A/B/K".into(), "/N".into()],
            &["/A/B/K".into()],
            &[
                ("/A".into(), "x".into()),
                ("/A".into(), "y".into()),
                ("/A/B/K".into(), "time".into()),
            ],
        )
        .unwrap();
        assert!(out.starts_with("#usda 1.0\n# a comment kept\ndef \"A\"\n{\n    uniform float x = 2.5 # one\n    uniform float[] y = [0.1, -3e-7, 1e20]\n"), "{out}");
        assert!(out.contains("    def \"B\"\n    {\n\n        def PainterlyPoseKey \"K\"\n        {\n            uniform double time = 40\n        }\n    }\n}\n"), "{out}");
        assert!(out.ends_with("}\n\nover \"N\"\n{\n}\n"), "{out}");
        // openusd reads back what was spliced.
        let back = parse(&out);
        let v = back.get_field(&sdf::Path::new("/A.y").unwrap(), "default").unwrap();
        assert_eq!(*v, Value::FloatVec(vec![0.1, -3e-7, 1e20]));
        assert!(back.has_spec(&sdf::Path::new("/A/B/K.time").unwrap()));
    }

    #[test]
    fn splices_headers_blank_lines_comments_and_unterminated_text_exactly() {
        // An `over` that becomes a typed `def`; a trailing comment two
        // spaces after the last property; a `{}` on one line that gains an
        // attribute and a child at the same offset; no newline at the end.
        let text = "#usda 1.0\nover \"O\"\n{\n    float a = 1  # c\n}\ndef \"E\" {}";
        let mut data = sdf::Data::new();
        for (p, spec, ty) in [
            ("/O", Specifier::Def, "Xform"),
            ("/E", Specifier::Def, ""),
            ("/E/K", Specifier::Def, ""),
            ("/N", Specifier::Def, ""),
            ("/N/C1", Specifier::Def, ""),
            ("/N/C1/G1", Specifier::Def, ""),
            ("/N/C1/G2", Specifier::Def, ""),
            ("/N/C2", Specifier::Def, ""),
        ] {
            let s = data.create_spec(sdf::Path::new(p).unwrap(), sdf::SpecType::Prim);
            s.add("specifier", Value::Specifier(spec));
            if !ty.is_empty() {
                s.add("typeName", Value::Token(ty.into()));
            }
        }
        for p in ["/O.b", "/E.x", "/N.x"] {
            let s = data.create_spec(sdf::Path::new(p).unwrap(), sdf::SpecType::Attribute);
            s.add("typeName", Value::Token("float".into()));
            s.add("default", Value::Float(2.0));
        }
        let prims: Vec<String> = ["/O", "/E/K", "/N", "/N/C1", "/N/C1/G1", "/N/C1/G2", "/N/C2"]
            .map(String::from)
            .to_vec();
        let attrs: Vec<(String, String)> = [("/O", "b"), ("/E", "x"), ("/N", "x")]
            .map(|(p, n)| (p.into(), n.into()))
            .to_vec();
        let out = splice(text, &data, &prims, &["/O".into()], &attrs).unwrap();
        // By the layout rules: the new attribute goes after the comment that
        // ends the last property's line; the one-line `{}` gets the child
        // block (a newline first, the child one level in) and then the
        // attribute (before `}`, which moves to a line of its own), in the
        // order the edits were made (usd-core reads either order); a new
        // root prim starts after a newline added to the unterminated text
        // and a blank line; inside a new prim, a blank line separates a
        // child from an attribute or a sibling before it, not from `{`.
        let expected = [
            "#usda 1.0",
            "def Xform \"O\"",
            "{",
            "    float a = 1  # c",
            "    float b = 2",
            "}",
            "def \"E\" {",
            "    def \"K\"",
            "    {",
            "    }",
            "",
            "    float x = 2",
            "}",
            "",
            "def \"N\"",
            "{",
            "    float x = 2",
            "",
            "    def \"C1\"",
            "    {",
            "        def \"G1\"",
            "        {",
            "        }",
            "",
            "        def \"G2\"",
            "        {",
            "        }",
            "    }",
            "",
            "    def \"C2\"",
            "    {",
            "    }",
            "}",
            "",
        ]
        .join("\n");
        assert_eq!(out, expected);
        let back = parse(&out);
        for p in ["/O.b", "/E.x", "/E/K", "/N.x", "/N/C1/G2", "/N/C2"] {
            assert!(back.has_spec(&sdf::Path::new(p).unwrap()), "{p}");
        }
    }
}
