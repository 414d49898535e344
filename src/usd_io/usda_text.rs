//! A lexer for `.usda` text and a scanner of its block structure.
//!
//! Two jobs need usda text without openusd's parser:
//!
//! - the composition guard measures bracket nesting *before* openusd parses
//!   (its parser recurses once per level and overflows the stack near 10,000);
//! - in-place edits splice the edited statements into the original text, so
//!   everything else stays byte for byte (see [`super::usda_splice`]).
//!
//! Token rules follow openusd 0.8's lexer: whitespace, `#` line comments and
//! `/* */` block comments are skipped; strings are `"…"`/`'…'` with
//! backslash escapes or `"""…"""`/`'''…'''`; `<…>` is a path, `@…@` and
//! `@@@…@@@` are asset paths; identifiers may hold `:` namespaces.

use std::ops::Range;

/// The kind of a token.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A name or keyword (`def`, `float3`, `primvars:displayColor`).
    Ident,
    /// A quoted string, quotes included in the span.
    Str,
    /// A number.
    Num,
    /// `<path>`.
    PathRef,
    /// `@asset@` or `@@@asset@@@`.
    Asset,
    /// One punctuation character.
    Punct(u8),
}

/// A token: its kind and byte range in the text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Token {
    pub kind: Kind,
    pub span: Range<usize>,
}

/// A lexing failure: byte offset and what was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LexError {
    pub offset: usize,
    pub message: &'static str,
}

/// Streams the tokens of usda text.
pub struct Lexer<'a> {
    s: &'a [u8],
    i: usize,
}

impl<'a> Lexer<'a> {
    pub fn new(text: &'a [u8]) -> Self {
        Lexer { s: text, i: 0 }
    }

    fn skip_trivia(&mut self) {
        let s = self.s;
        loop {
            while self.i < s.len() && matches!(s[self.i], b' ' | b'\t' | b'\r' | b'\n' | 0x0c) {
                self.i += 1;
            }
            if self.i < s.len() && s[self.i] == b'#' {
                while self.i < s.len() && s[self.i] != b'\n' && s[self.i] != b'\r' {
                    self.i += 1;
                }
                continue;
            }
            if s[self.i..].starts_with(b"/*") {
                match find(&s[self.i + 2..], b"*/") {
                    Some(k) => {
                        self.i += 2 + k + 2;
                        continue;
                    }
                    // An unclosed block comment is not a comment for openusd
                    // either; leave it to be reported as an unexpected '/'.
                    None => return,
                }
            }
            return;
        }
    }
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

fn is_ident_start(c: u8) -> bool {
    c.is_ascii_alphabetic() || c == b'_'
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

impl Iterator for Lexer<'_> {
    type Item = Result<Token, LexError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.skip_trivia();
        let s = self.s;
        let start = self.i;
        if start >= s.len() {
            return None;
        }
        let err = |message| Some(Err(LexError { offset: start, message }));
        let c = s[start];
        let tok = |this: &mut Self, kind, end: usize| {
            this.i = end;
            Some(Ok(Token { kind, span: start..end }))
        };
        match c {
            b'"' | b'\'' => {
                // An unclosed triple quote lexes as an empty string and
                // more, as in openusd (its longest match falls back).
                let triple = [c, c, c];
                if s[start..].starts_with(&triple) {
                    if let Some(k) = find(&s[start + 3..], &triple) {
                        return tok(self, Kind::Str, start + 3 + k + 3);
                    }
                }
                let mut j = start + 1;
                while j < s.len() {
                    match s[j] {
                        // An escape takes any character but a newline
                        // (openusd's `\\.`): backslash-newline ends the lexeme.
                        b'\\' if s.get(j + 1) == Some(&b'\n') => break,
                        b'\\' => j += 2,
                        x if x == c => return tok(self, Kind::Str, j + 1),
                        _ => j += 1,
                    }
                }
                err("unterminated string")
            }
            b'<' => match s[start + 1..].iter().position(|&x| x == b'>') {
                Some(k) => tok(self, Kind::PathRef, start + 1 + k + 1),
                None => err("unterminated path"),
            },
            b'@' => {
                // An unclosed `@@@` falls back the same way (`@@` is empty).
                if s[start..].starts_with(b"@@@") {
                    if let Some(k) = find(&s[start + 3..], b"@@@") {
                        return tok(self, Kind::Asset, start + 3 + k + 3);
                    }
                }
                match s[start + 1..].iter().position(|&x| x == b'@') {
                    Some(k) => tok(self, Kind::Asset, start + 1 + k + 1),
                    None => err("unterminated asset path"),
                }
            }
            b'0'..=b'9' => tok(self, Kind::Num, number_end(s, start)),
            b'+' | b'-' if s.get(start + 1).is_some_and(|&d| d.is_ascii_digit() || d == b'.') => {
                let end = number_end(s, start + 1);
                if end > start + 1 {
                    tok(self, Kind::Num, end)
                } else {
                    tok(self, Kind::Punct(c), start + 1)
                }
            }
            b'=' | b',' | b':' | b';' | b'&' | b'.' | b'(' | b')' | b'{' | b'}' | b'[' | b']' | b'+' | b'-' => {
                tok(self, Kind::Punct(c), start + 1)
            }
            c if is_ident_start(c) => {
                let mut j = start + 1;
                while j < s.len() && is_ident(s[j]) {
                    j += 1;
                }
                if j < s.len() && s[j] == b':' {
                    j += 1;
                    while j < s.len() && (is_ident(s[j]) || s[j] == b':') {
                        j += 1;
                    }
                }
                tok(self, Kind::Ident, j)
            }
            _ => err("unexpected character"),
        }
    }
}

/// End of a number starting at `i` (digits, optional fraction and exponent;
/// a leading '.' fraction is allowed after a sign).
fn number_end(s: &[u8], mut i: usize) -> usize {
    let digits = |s: &[u8], mut i: usize| {
        while i < s.len() && s[i].is_ascii_digit() {
            i += 1;
        }
        i
    };
    i = digits(s, i);
    if i + 1 < s.len() && s[i] == b'.' && s[i + 1].is_ascii_digit() {
        i = digits(s, i + 1);
    }
    if i < s.len() && (s[i] == b'e' || s[i] == b'E') {
        let mut j = i + 1;
        if j < s.len() && (s[j] == b'+' || s[j] == b'-') {
            j += 1;
        }
        if j < s.len() && s[j].is_ascii_digit() {
            i = digits(s, j);
        }
    }
    i
}

/// The deepest bracket nesting (`(`, `[`, `{`) of usda text and the byte
/// offset where it is first reached. Lexing errors end the scan (openusd
/// reports them itself); brackets inside strings and comments do not count.
pub fn max_nesting(text: &[u8]) -> (usize, usize) {
    let (mut depth, mut max, mut at) = (0usize, 0usize, 0usize);
    for t in Lexer::new(text) {
        let Ok(t) = t else { break };
        match t.kind {
            Kind::Punct(b'(' | b'[' | b'{') => {
                depth += 1;
                if depth > max {
                    max = depth;
                    at = t.span.start;
                }
            }
            Kind::Punct(b')' | b']' | b'}') => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    (max, at)
}

/// 1-based line number of byte `offset`.
pub fn line_of(text: &[u8], offset: usize) -> usize {
    text[..offset.min(text.len())].iter().filter(|&&c| c == b'\n').count() + 1
}

/// The unquoted content of a string token, escapes resolved as USD's text
/// format reads them (and openusd's parser, whose names usda_splice must
/// match): `\a \b \f \n \r \t \v`, `\xH[H]`, octal `\O[O[O]]`; any other
/// escaped character stands for itself, and a final lone backslash (possible
/// only in a triple-quoted string) is dropped.
pub fn unquote(raw: &str) -> String {
    let inner = if raw.len() >= 6 && (raw.starts_with("\"\"\"") || raw.starts_with("'''")) {
        &raw[3..raw.len() - 3]
    } else if raw.len() >= 2 {
        &raw[1..raw.len() - 1]
    } else {
        return String::new();
    };
    let mut out = String::with_capacity(inner.len());
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        let Some(e) = chars.next() else { break };
        let (radix, first, max_digits) = match e {
            'a' => (0, 0x7, 0),
            'b' => (0, 0x8, 0),
            'f' => (0, 0xc, 0),
            'n' => (0, u32::from('\n'), 0),
            'r' => (0, u32::from('\r'), 0),
            't' => (0, u32::from('\t'), 0),
            'v' => (0, 0xb, 0),
            'x' => (16, 0, 2),
            '0'..='7' => (8, u32::from(e) - u32::from('0'), 2),
            other => (0, u32::from(other), 0),
        };
        // A numeric escape takes as many of its digits as follow, up to its
        // maximum; `\x` with none names NUL, as in C++.
        let mut value = first;
        for _ in 0..max_digits {
            match chars.peek().and_then(|d| d.to_digit(radix)) {
                Some(d) => {
                    value = value * radix + d;
                    chars.next();
                }
                None => break,
            }
        }
        out.extend(char::from_u32(value));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(s: &str) -> Vec<(Kind, String)> {
        // Bounded like `our_tokens` below.
        Lexer::new(s.as_bytes())
            .take(s.len() + 1)
            .map(|t| t.unwrap())
            .map(|t| (t.kind, s[t.span].to_string()))
            .collect()
    }

    #[test]
    fn lexes_usda_tokens() {
        let s = "#usda 1.0\n( doc = \"\"\"a { b\"\"\" )\ndef Xform \"A\" (\n    prepend inherits = </_cls> # { not counted\n)\n{\n    float3[] x:y = [(1, -2.5e-3, .5)] /* } */\n    asset a = @@@x@y@@@\n}\n";
        let k = kinds(s);
        assert_eq!(k[0], (Kind::Punct(b'('), "(".into()));
        assert_eq!(k[3], (Kind::Str, "\"\"\"a { b\"\"\"".into()));
        assert!(k.contains(&(Kind::PathRef, "</_cls>".into())));
        assert!(k.contains(&(Kind::Ident, "x:y".into())));
        assert!(k.contains(&(Kind::Num, "-2.5e-3".into())));
        assert!(k.contains(&(Kind::Asset, "@@@x@y@@@".into())));
        assert_eq!(max_nesting(s.as_bytes()).0, 3);
        assert!(Lexer::new(b"\"open").any(|t| t.is_err()));
    }

    #[test]
    fn nesting_of_deep_prims() {
        let n = 50;
        let text = format!("#usda 1.0\n{}{}", "def \"P\" {\n".repeat(n), "}\n".repeat(n));
        assert_eq!(max_nesting(text.as_bytes()).0, n);
        assert_eq!(unquote("\"a\\\"b\""), "a\"b");
    }

    /// openusd's lexer over `s`: (kind, span) up to its first error, and
    /// that error's offset. Keywords and identifiers are our `Ident`; its
    /// `#usda` header token is a comment to us.
    fn openusd_tokens(s: &str) -> (Vec<(Kind, Range<usize>)>, Option<usize>) {
        use logos::Logos;
        use openusd::usda::token::Token as T;
        let mut lex = T::lexer(s);
        let mut out = Vec::new();
        while let Some(t) = lex.next() {
            let kind = match t {
                Err(_) => return (out, Some(lex.span().start)),
                Ok(T::Magic(_)) => continue,
                Ok(T::String(_)) => Kind::Str,
                Ok(T::Number(_)) => Kind::Num,
                Ok(T::PathRef(_)) => Kind::PathRef,
                Ok(T::AssetRef(_)) => Kind::Asset,
                Ok(T::Punctuation(c)) => Kind::Punct(c as u8),
                Ok(_) => Kind::Ident,
            };
            out.push((kind, lex.span()));
        }
        (out, None)
    }

    fn our_tokens(s: &str) -> (Vec<(Kind, Range<usize>)>, Option<usize>) {
        let mut out = Vec::new();
        // Every token takes a byte, so a lexer that stops advancing fails
        // here (one token too many) instead of hanging.
        for t in Lexer::new(s.as_bytes()).take(s.len() + 1) {
            match t {
                Ok(t) => out.push((t.kind, t.span)),
                Err(e) => return (out, Some(e.offset)),
            }
        }
        (out, None)
    }

    #[test]
    fn tokens_match_openusds_lexer() {
        use crate::interp::testutil::Lcg;
        const PIECES: &[&str] = &[
            "def",
            "over",
            "float3",
            "primvars:displayColor",
            "x:y:",
            "_a1",
            "inf",
            "None",
            "e",
            "42",
            "3.14",
            "1e5",
            "1.5E-3",
            "-2",
            "+.5",
            "-.5e+2",
            "7.",
            "1e",
            "2e+",
            "0.5",
            "\"a b\"",
            "'x'",
            "\"esc \\\" q\"",
            "\"\"",
            "'it\\'s'",
            "\"\"\"multi\nline \" \"\" end\"\"\"",
            "'''t ' '' '''",
            "\"tab\\tnew\\n\"",
            "</A/B.c>",
            "<>",
            "@a.usda@",
            "@@@a@b@@b@@@",
            "@@",
            "=",
            ",",
            ":",
            ";",
            "&",
            ".",
            "(",
            ")",
            "{",
            "}",
            "[",
            "]",
            "+",
            "-",
            "# line comment { [\n",
            "/* block ( */",
            "/* multi\nline */",
            "/**/",
            "#usda 1.0\n",
        ];
        const BAD: &[&str] = &[
            "\"open",
            "'open",
            "\"line\\\ncontinued\"",
            "'line\\\ncontinued'",
            "\"\"\"open\"\"",
            "<open",
            "@open",
            "@@@open@@",
            "$",
            "/* open",
            "/",
            "!",
        ];
        const SPACE: &[&str] = &["", " ", "\n", "\t", "\r\n", "  "];
        let mut rng = Lcg::new(11);
        for case in 0..3000 {
            let mut text = String::new();
            for _ in 0..1 + rng.below(30) {
                text.push_str(PIECES[rng.below(PIECES.len())]);
                text.push_str(SPACE[rng.below(SPACE.len())]);
            }
            if case % 4 == 0 {
                text.push_str(BAD[rng.below(BAD.len())]);
                text.push_str(PIECES[rng.below(PIECES.len())]);
            }
            assert_eq!(our_tokens(&text), openusd_tokens(&text), "case {case}: {text:?}");
        }
    }

    #[test]
    fn nesting_counts_brackets_outside_strings_and_comments() {
        let text = b"( [ \"(((\" { /* [[[ */ } ] # {{{\n ) [ ( ) ]";
        // Depth 3 first reached at the '{' (offset 10).
        assert_eq!(max_nesting(text), (3, 10));
        // Closing more than was opened does not go below zero.
        assert_eq!(max_nesting(b") ) ( ["), (2, 6));
        // A lexing error ends the scan.
        assert_eq!(max_nesting(b"( $ ( ( ("), (1, 0));
        assert_eq!(max_nesting(b""), (0, 0));
        assert_eq!(max_nesting(b"{ } { }"), (1, 0));
    }

    #[test]
    fn lines_and_unquoting() {
        let text = b"a\nbc\n\nd";
        assert_eq!([0, 1, 2, 4, 5, 6, 99].map(|o| line_of(text, o)), [1, 1, 2, 2, 3, 4, 4]);
        assert_eq!(unquote("\"plain\""), "plain");
        assert_eq!(unquote("'single'"), "single");
        assert_eq!(unquote("\"\"\"tri\"ple\"\"\""), "tri\"ple");
        assert_eq!(unquote("'''x'''"), "x");
        assert_eq!(unquote("\"\"\"\"\"\""), "");
        assert_eq!(unquote("\"a\\nb\\tc\\rd\\\\e\\\"f\\qg\""), "a\nb\tc\rd\\e\"fqg");
        // A lone final backslash is dropped, as openusd's parser drops it.
        assert_eq!(unquote("\"end\\\""), "end");
        assert_eq!(unquote("\"\""), "");
        assert_eq!(unquote("\""), "");
        assert_eq!(unquote(""), "");
        // Five characters cannot be a triple-quoted string.
        assert_eq!(unquote("\"\"\"\"\""), "\"\"\"");
    }

    #[test]
    fn tokens_ending_the_text_and_sign_edges_match_openusd() {
        // A sign before a letter is punctuation ("-e5" is '-' then `e5`, not
        // an exponent-only number); a sign before a bare '.' stays a sign;
        // every token kind and a comment may end the text.
        for text in [
            "-e5",
            "+e-2 x",
            "-.",
            "-.x",
            "+. 1",
            "7.",
            "1e",
            "2e+",
            "3e-",
            "1.5",
            "9",
            "a:b",
            "a # c",
            "# c\r{",
            "a /* c */",
        ] {
            assert_eq!(our_tokens(text), openusd_tokens(text), "{text:?}");
        }
        // By hand, so the comparison above cannot pass with both lexers wrong.
        let by_hand: Vec<_> = Lexer::new(b"-e5 -. 7.")
            .take(9)
            .map(|t| t.unwrap())
            .map(|t| (t.kind, t.span))
            .collect();
        let (minus, dot) = (Kind::Punct(b'-'), Kind::Punct(b'.'));
        assert_eq!(
            by_hand,
            [
                (minus, 0..1),
                (Kind::Ident, 1..3),
                (minus, 4..5),
                (dot, 5..6),
                (Kind::Num, 7..8),
                (dot, 8..9)
            ]
        );
    }

    #[test]
    fn unquote_resolves_numeric_and_control_escapes_like_usd() {
        // usd-core (TfEscapeString) reads `doc = "\x41\101\a\v"` as
        // "AA\x07\x0b" and `def "\x41"` as /A; so does openusd's parser.
        assert_eq!(unquote("\"\\x41\\101\\a\\v\""), "AA\u{7}\u{b}");
        // Digits stop at their maximum or at a non-digit; `\x` alone is NUL
        // (usd-core reads this one as "A4A1\x04g8\x00z\x00").
        assert_eq!(unquote("'\\x414\\1011\\x4g\\8\\xz\\0'"), "A4A1\u{4}g8\u{0}z\u{0}");
        // `\377` is the byte 0xFF to usd-core, which no Rust string holds;
        // openusd names it U+00FF, and so does painterly.
        assert_eq!(unquote("'\\b\\f\\377'"), "\u{8}\u{c}\u{ff}");
    }
}
