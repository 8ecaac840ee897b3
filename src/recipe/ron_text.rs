//! RON text read as code: its comments and string literals blanked out,
//! and byte offsets in it as the `line:col` a message gives.

use std::collections::HashMap;

/// A copy of RON `text` with the comments (block comments nested, as RON
/// reads them) and the contents of string literals blanked to spaces (the quotes kept), byte for byte, so that
/// offsets (and the original text's line:col) stay valid: names and
/// brackets in comments and strings do not count when searching it.
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

/// A map key `"name":` written in RON text as code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct KeyDefinition {
    /// Byte offset of its opening quote.
    pub offset: usize,
    /// The 1-based line and column of that quote.
    pub line_col: (usize, usize),
}

/// Every map key `"name":` of RON `text` written as code (not in a comment
/// or inside another string), each at its first definition. Two passes
/// over the text however many keys it has, so that a recipe of thousands
/// of materials is indexed in linear time (looking each up on its own
/// took time quadratic in their number).
pub(crate) fn key_definitions(text: &str) -> HashMap<String, KeyDefinition> {
    let code = blank_comments_and_strings(text);
    // The keys' quotes, in order: in `code` a string's contents are
    // blanked, so its closing quote is the next quote.
    let mut quotes = Vec::new();
    let mut i = 0;
    while let Some(open) = code[i..].iter().position(|&b| b == b'"').map(|k| i + k) {
        let Some(close) = code[open + 1..].iter().position(|&b| b == b'"') else {
            break;
        };
        let close = open + 1 + close;
        let next = code[close + 1..].iter().find(|b| !b.is_ascii_whitespace());
        if next == Some(&b':') {
            quotes.push((open, close));
        }
        i = close + 1;
    }
    // Their line:col, in one sweep over the characters.
    let mut keys = HashMap::new();
    let mut pending = quotes.into_iter().peekable();
    let (mut line, mut col) = (1, 1);
    for (i, c) in text.char_indices() {
        while let Some(&(open, close)) = pending.peek().filter(|(open, _)| *open == i) {
            keys.entry(text[open + 1..close].to_string())
                .or_insert(KeyDefinition {
                    offset: open,
                    line_col: (line, col),
                });
            pending.next();
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

/// The end (exclusive byte offset) of the value that follows the first
/// `:` at or after `from` in RON `text`: up to the `,` or the closing
/// bracket that ends it, its own brackets matched, strings and comments
/// skipped; the text's end when nothing ends it.
pub(crate) fn value_end(text: &str, from: usize) -> usize {
    let bytes = text.as_bytes();
    let Some(colon) = text[from..].find(':').map(|k| from + k) else {
        return bytes.len();
    };
    let (mut depth, mut i) = (0usize, colon + 1);
    while i < bytes.len() {
        match bytes[i] {
            b'"' => {
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += if bytes[i] == b'\\' { 2 } else { 1 };
                }
            }
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                i = text[i..].find('\n').map_or(bytes.len(), |k| i + k);
                continue;
            }
            b'/' if bytes.get(i + 1) == Some(&b'*') => {
                i = block_comment_end(bytes, i);
                continue;
            }
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' if depth == 0 => return i,
            b')' | b']' | b'}' => depth -= 1,
            b',' if depth == 0 => return i,
            _ => {}
        }
        i += 1;
    }
    bytes.len()
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
        let text =
            "// \"a\": no\n{\"a\": M(x: \"b\", y: [1, 2]) /* ) */, \"c\" :\n N(),\n \"a\": again}";
        let keys = key_definitions(text);
        assert_eq!(keys.len(), 2);
        let a = keys["a"];
        assert_eq!(a.offset, text.find("{\"a\"").unwrap() + 1);
        assert_eq!(a.line_col, line_col_of_offset(text, a.offset));
        assert_eq!(keys["c"].line_col, (2, 37));
        assert_eq!(
            keys["c"].line_col,
            line_col_of_offset(text, keys["c"].offset)
        );
        // The value ends at its comma, its brackets and comment skipped.
        let end = value_end(text, a.offset);
        assert_eq!(
            &text[a.offset..end],
            "\"a\": M(x: \"b\", y: [1, 2]) /* ) */"
        );
        assert_eq!(
            &text[keys["c"].offset..value_end(text, keys["c"].offset)],
            "\"c\" :\n N()"
        );
        // The last value ends at the map's closing bracket.
        let last = text.rfind("\"a\"").unwrap();
        assert_eq!(&text[last..value_end(text, last)], "\"a\": again");
    }
}
