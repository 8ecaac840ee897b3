//! RON text read as code: its comments and string literals blanked out,
//! and byte offsets in it as the `line:col` a message gives.

use std::collections::HashMap;

/// A copy of RON `text` with the comments (block comments nested, as RON
/// reads them) and the contents of string literals, raw ones included,
/// blanked to spaces (the quotes kept), byte for byte, so that offsets
/// (and the original text's line:col) stay valid: names and brackets in
/// comments and strings do not count when searching it.
pub(crate) fn blank_comments_and_strings(text: &str) -> Vec<u8> {
    let bytes = text.as_bytes();
    let n = bytes.len();
    let mut code = bytes.to_vec();
    let mut i = 0;
    while i < n {
        // Blank [from, to) and go on at `next`.
        let (from, to, next) = match bytes[i] {
            b'"' => {
                let mut k = i + 1;
                while k < n && bytes[k] != b'"' {
                    k += if bytes[k] == b'\\' { 2 } else { 1 };
                }
                (i + 1, k.min(n), k + 1)
            }
            // A raw string, `r"…"` or `r#"…"#` (any number of `#`), not
            // the end of a name.
            b'r' if i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_') => {
                let hashes = bytes[i + 1..].iter().take_while(|&&c| c == b'#').count();
                if bytes.get(i + 1 + hashes) != Some(&b'"') {
                    i += 1;
                    continue;
                }
                let open = i + 1 + hashes;
                let mut close = b"\"".to_vec();
                close.resize(1 + hashes, b'#');
                let end = bytes[open + 1..]
                    .windows(close.len())
                    .position(|w| w == close.as_slice())
                    .map_or(n, |k| open + 1 + k);
                (open + 1, end, end + close.len())
            }
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                let end = bytes[i..].iter().position(|&c| c == b'\n');
                let to = end.map_or(n, |e| i + e);
                (i, to, to)
            }
            b'/' if bytes.get(i + 1) == Some(&b'*') => {
                let k = block_comment_end(bytes, i);
                (i, k, k)
            }
            _ => {
                i += 1;
                continue;
            }
        };
        code[from..to].fill(b' ');
        i = next;
    }
    code
}

/// The offset just past the block comment that opens at `start` (where
/// `bytes` holds `/*`), or the end of `bytes` when it is never closed.
/// RON's block comments nest: `/* a /* b */ c */` is one comment.
pub(crate) fn block_comment_end(bytes: &[u8], start: usize) -> usize {
    let (mut depth, mut k) = (1, start + 2);
    while k < bytes.len() && depth > 0 {
        if bytes[k..].starts_with(b"/*") {
            depth += 1;
            k += 2;
        } else if bytes[k..].starts_with(b"*/") {
            depth -= 1;
            k += 2;
        } else {
            k += 1;
        }
    }
    k.min(bytes.len())
}

/// A map key `"name":` written in RON text as code, and its value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct KeyDefinition {
    /// Byte offset of its opening quote.
    pub offset: usize,
    /// The 1-based line and column of that quote.
    pub line_col: (usize, usize),
    /// Byte offset just past its value: the `,` or the closing bracket
    /// that ends it (the text's end when nothing does).
    pub value_end: usize,
}

/// Every map key `"name":` of RON `text` written as code (not in a comment
/// or inside another string), each at its first definition, with where
/// its value ends (its own brackets matched; brackets in strings and
/// comments not counted). Linear in the text for a recipe's keys, whose
/// values hold no keys of their own, so that a recipe of thousands of
/// materials is indexed at once (looking each up on its own took time
/// quadratic in their number).
pub(crate) fn key_definitions(text: &str) -> HashMap<String, KeyDefinition> {
    let code = blank_comments_and_strings(text);
    // The keys' quotes and colons, in order: in `code` a string's contents
    // are blanked, so its closing quote is the next quote.
    let mut found = Vec::new();
    let mut i = 0;
    while let Some(open) = code[i..].iter().position(|&b| b == b'"').map(|k| i + k) {
        let Some(close) = code[open + 1..].iter().position(|&b| b == b'"') else {
            break;
        };
        let close = open + 1 + close;
        let colon = code[close + 1..]
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .map(|k| close + 1 + k)
            .filter(|&k| code[k] == b':');
        if let Some(colon) = colon {
            found.push((open, close, value_end(&code, colon + 1)));
        }
        i = close + 1;
    }
    // Their line:col, in one sweep over the characters.
    let mut keys = HashMap::new();
    let mut pending = found.into_iter().peekable();
    let (mut line, mut col) = (1, 1);
    for (i, c) in text.char_indices() {
        while let Some((open, close, value_end)) = pending.next_if(|(open, ..)| *open == i) {
            keys.entry(text[open + 1..close].to_string())
                .or_insert(KeyDefinition {
                    offset: open,
                    line_col: (line, col),
                    value_end,
                });
        }
        if pending.peek().is_none() {
            break;
        }
        (line, col) = if c == '\n' {
            (line + 1, 1)
        } else {
            (line, col + 1)
        };
    }
    keys
}

/// The end (exclusive) of the value that starts at `from` in `code` (RON
/// text with its comments and strings blanked): the `,` or the closing
/// bracket at its own depth, else the end.
fn value_end(code: &[u8], from: usize) -> usize {
    let mut depth = 0usize;
    for (k, &c) in code.iter().enumerate().skip(from) {
        match c {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' | b',' if depth == 0 => return k,
            b')' | b']' | b'}' => depth -= 1,
            _ => {}
        }
    }
    code.len()
}

/// 1-based line and column of a byte offset.
pub fn line_col_of_offset(source: &str, offset: usize) -> (usize, usize) {
    let before = &source[..offset.min(source.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comments_nest_and_strings_keep_their_quotes() {
        let text = "a /* b /* ( */ c ) */ d \"e ( \\\" f\" // g (\nh";
        let code = String::from_utf8(blank_comments_and_strings(text)).unwrap();
        assert_eq!(code.len(), text.len());
        assert_eq!(code.replace(' ', ""), "ad\"\"\nh");
    }

    #[test]
    fn keys_are_found_as_code_with_their_places_and_values() {
        let text = "// \"a\": no\n{\"a\": M(x: \"b)\", y: [1, 2]) /* ) */, \"c\" :\n N(),\n \"a\": again, \"d:e\": r#\"f\" (\"#, \"g\": 1}";
        let keys = key_definitions(text);
        assert_eq!(keys.len(), 4);
        let a = keys["a"];
        assert_eq!(a.offset, text.find("{\"a\"").unwrap() + 1);
        assert_eq!(a.line_col, line_col_of_offset(text, a.offset));
        assert_eq!(keys["c"].line_col, (2, 38));
        assert_eq!(
            keys["c"].line_col,
            line_col_of_offset(text, keys["c"].offset)
        );
        // A value ends at its comma, its brackets, strings and comment
        // skipped; the last at the map's closing bracket.
        let value = |key: &str| &text[keys[key].offset..keys[key].value_end];
        assert_eq!(value("a"), "\"a\": M(x: \"b)\", y: [1, 2]) /* ) */");
        assert_eq!(value("c"), "\"c\" :\n N()");
        // A colon in a name, a raw string with a quote and a bracket.
        assert_eq!(value("d:e"), "\"d:e\": r#\"f\" (\"#");
        assert_eq!(value("g"), "\"g\": 1");
    }

    #[test]
    fn raw_strings_are_blanked_like_strings() {
        let text = "a: r#\"x \"( y\"#, b: r\"z\", bar\"";
        let code = String::from_utf8(blank_comments_and_strings(text)).unwrap();
        assert_eq!(code.len(), text.len());
        assert_eq!(code.replace(' ', ""), "a:r#\"\"#,b:r\"\",bar\"");
    }
}
