//! RON text read as code: its comments and string literals blanked out,
//! and byte offsets in it as the `line:col` a message gives.

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
                // RON's block comments nest.
                let (mut depth, mut k) = (1, i + 2);
                while k < n && depth > 0 {
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
}
