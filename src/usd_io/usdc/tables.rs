//! The interning tables behind the structural sections: tokens, strings,
//! fields, field sets and specs, each deduplicated as usd-core does, and the
//! bytes of their sections.

use std::collections::{HashMap, HashSet};

use super::compress::{lz4_frame, put_compressed_ints};

/// The TOKENS table. Index 0 is `";-)"`, a token no prim property can be
/// named, as usd-core reserves it: prim property elements are stored as
/// negated token indexes, and `-0` would read back as a prim child
/// (usd-core's GitHub issue 811).
pub struct Tokens {
    index: HashMap<String, u32>,
    items: Vec<String>,
}

impl Tokens {
    pub fn new() -> Tokens {
        let mut t = Tokens {
            index: HashMap::new(),
            items: Vec::new(),
        };
        t.intern(";-)");
        t
    }

    pub fn intern(&mut self, s: &str) -> u32 {
        if let Some(&i) = self.index.get(s) {
            return i;
        }
        let i = self.items.len() as u32;
        self.index.insert(s.to_string(), i);
        self.items.push(s.to_string());
        i
    }

    /// TOKENS: the count, the size of the NUL-terminated token text, then
    /// that text LZ4-compressed after its compressed size.
    pub fn write_section(&self, out: &mut Vec<u8>) {
        let mut text = Vec::new();
        for t in &self.items {
            text.extend_from_slice(t.as_bytes());
            text.push(0);
        }
        out.extend_from_slice(&(self.items.len() as u64).to_le_bytes());
        out.extend_from_slice(&(text.len() as u64).to_le_bytes());
        let size_at = out.len();
        out.extend_from_slice(&0u64.to_le_bytes());
        lz4_frame(&text, out);
        let size = (out.len() - size_at - 8) as u64;
        out[size_at..size_at + 8].copy_from_slice(&size.to_le_bytes());
    }
}

/// The STRINGS table: strings are tokens, listed here by token index.
#[derive(Default)]
pub struct Strings {
    index: HashMap<u32, u32>,
    items: Vec<u32>,
}

impl Strings {
    pub fn intern(&mut self, s: &str, tokens: &mut Tokens) -> u32 {
        let token = tokens.intern(s);
        if let Some(&i) = self.index.get(&token) {
            return i;
        }
        let i = self.items.len() as u32;
        self.index.insert(token, i);
        self.items.push(token);
        i
    }

    /// STRINGS: the count, then each string's token index (uncompressed).
    pub fn write_section(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(self.items.len() as u64).to_le_bytes());
        for t in &self.items {
            out.extend_from_slice(&t.to_le_bytes());
        }
    }
}

/// Fields (a name token and a value rep), field sets (runs of field indexes
/// ended by `u32::MAX`) and specs (path, field set, spec type).
#[derive(Default)]
pub struct Specs {
    field_index: HashMap<(u32, u64), u32>,
    fields: Vec<(u32, u64)>,
    fieldset_index: HashMap<Vec<u32>, u32>,
    fieldsets: Vec<u32>,
    specs: Vec<(u32, u32, u32)>,
    spec_paths: HashSet<u32>,
}

impl Specs {
    pub fn field(&mut self, token: u32, rep: u64) -> u32 {
        *self.field_index.entry((token, rep)).or_insert_with(|| {
            self.fields.push((token, rep));
            (self.fields.len() - 1) as u32
        })
    }

    fn fieldset(&mut self, fields: Vec<u32>) -> u32 {
        if let Some(&i) = self.fieldset_index.get(&fields) {
            return i;
        }
        let start = self.fieldsets.len() as u32;
        self.fieldsets.extend_from_slice(&fields);
        self.fieldsets.push(u32::MAX);
        self.fieldset_index.insert(fields, start);
        start
    }

    /// Adds a spec; `false` if its path already has one.
    pub fn spec(&mut self, path: u32, spec_type: u32, fields: Vec<u32>) -> bool {
        if !self.spec_paths.insert(path) {
            return false;
        }
        let set = self.fieldset(fields);
        self.specs.push((path, set, spec_type));
        true
    }

    /// FIELDS: the count, the compressed name tokens, then the value reps
    /// LZ4-compressed after their compressed size.
    pub fn write_fields(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(self.fields.len() as u64).to_le_bytes());
        let tokens: Vec<u32> = self.fields.iter().map(|f| f.0).collect();
        put_compressed_ints(&tokens, out);
        let reps: Vec<u8> = self.fields.iter().flat_map(|f| f.1.to_le_bytes()).collect();
        let size_at = out.len();
        out.extend_from_slice(&0u64.to_le_bytes());
        lz4_frame(&reps, out);
        let size = (out.len() - size_at - 8) as u64;
        out[size_at..size_at + 8].copy_from_slice(&size.to_le_bytes());
    }

    /// FIELDSETS: the count, then the compressed runs.
    pub fn write_fieldsets(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(self.fieldsets.len() as u64).to_le_bytes());
        put_compressed_ints(&self.fieldsets, out);
    }

    /// SPECS: the count, then compressed path indexes, field set indexes and
    /// spec types.
    pub fn write_specs(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(self.specs.len() as u64).to_le_bytes());
        let column = |f: fn(&(u32, u32, u32)) -> u32| self.specs.iter().map(f).collect::<Vec<u32>>();
        put_compressed_ints(&column(|s| s.0), out);
        put_compressed_ints(&column(|s| s.1), out);
        put_compressed_ints(&column(|s| s.2), out);
    }
}
