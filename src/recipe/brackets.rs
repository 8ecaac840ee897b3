//! Where a RON file's brackets or quotes probably went wrong. RON stops at
//! the first token it cannot read, which for a missing `)`, `]`, `}` or
//! `"` is often lines later and says only what it expected there
//! ("Expected identifier"). This reads the file's brackets and its
//! indentation and names the opening bracket or quote left open.

use crate::recipe::ron_text::{blank_comments_and_strings, line_col_of_offset};

/// A bracket still open while the file is read.
#[derive(Clone, Copy, Debug)]
struct Open {
    /// `(`, `[` or `{`.
    bracket: u8,
    /// Its byte offset.
    offset: usize,
    /// The byte offset of its line's start.
    line_start: usize,
    /// The indentation (leading whitespace bytes) of its line.
    line_indent: usize,
    /// Whether nothing but whitespace follows it on its line.
    ends_line: bool,
    /// Whether the first line of code after its own is indented deeper
    /// (its contents are a block); None until that line is read.
    block: Option<bool>,
}

/// What looks wrong, and the byte offset where it shows.
struct Suspect {
    shows_at: usize,
    hint: String,
}

/// The closing bracket of an opening one.
fn closer_of(bracket: u8) -> u8 {
    match bracket {
        b'(' => b')',
        b'[' => b']',
        _ => b'}',
    }
}

/// A hint for an error at byte `error_offset` of RON `source` (appended to
/// RON's message): a string that the error lies in or just after and that
/// runs on past the end of its line, else the first bracket that looks left
/// open, if that shows before the end of the error's line (or the file
/// ends, `at_end`: nothing but comments follows the error). A bracket
/// looks left open when a closing bracket of another kind meets it, when
/// the file ends, and, where the file's indentation tells (its blocks'
/// contents indented deeper than their first line, tabs and spaces not
/// mixed), when a line as shallow as the bracket's own line follows its
/// block without closing it, or when the line after a bracket opened
/// within a line is no deeper and does not close it. None where the error
/// stands at the very closing bracket that shows the problem (RON's
/// message and its own hint are about that bracket).
pub(crate) fn open_bracket_hint(source: &str, error_offset: usize, at_end: bool) -> Option<String> {
    let code = blank_comments_and_strings(source);
    if let Some(hint) = runaway_string(source, &code, error_offset) {
        return Some(hint);
    }
    let suspect = open_bracket(source, &code)?;
    // RON may stop before the bracket that shows it, on the same line.
    let error_line_end = source[error_offset.min(source.len())..]
        .find('\n')
        .map_or(source.len(), |end| error_offset + end);
    let at_the_closer = suspect.shows_at == error_offset
        && matches!(code.get(error_offset), Some(b')' | b']' | b'}'));
    ((suspect.shows_at <= error_line_end || at_end) && !at_the_closer).then_some(suspect.hint)
}

/// The hint for a string literal that holds a line break where the error
/// lies inside it or after its closing quote on that quote's line: a
/// closing `"` missing pairs every later quote wrongly, and RON stops
/// there. (A string may hold line breaks: one far from the error is taken
/// as written.)
fn runaway_string(source: &str, code: &[u8], error_offset: usize) -> Option<String> {
    let mut quotes = code
        .iter()
        .enumerate()
        .filter(|(_, &c)| c == b'"')
        .map(|(i, _)| i);
    while let Some(open) = quotes.next() {
        if open >= error_offset {
            return None;
        }
        let close = quotes.next().unwrap_or(source.len());
        let close_line_end = source[close.min(source.len())..]
            .find('\n')
            .map_or(source.len(), |end| close + end);
        if error_offset <= close_line_end && source[open..close].contains('\n') {
            let (line, col) = line_col_of_offset(source, open);
            return Some(format!(
                " (is a closing `\"` missing? the string opened at {line}:{col} runs on past \
                 the end of its line)"
            ));
        }
    }
    None
}

/// The first bracket that looks left open, by the rules of
/// [`open_bracket_hint`].
fn open_bracket(source: &str, code: &[u8]) -> Option<Suspect> {
    let indentation_tells = indents_blocks(source, code) && !mixes_tabs_and_spaces(source, code);
    let mut stack: Vec<Open> = Vec::new();
    // A block closed on a deeper line than its opening one, and where.
    let mut closed_early: Option<(Open, usize)> = None;
    let mut line_start = 0;
    // Whether the line starts inside a string (an odd count of quotes
    // before it): its indentation is the string's text.
    let mut in_string = false;
    for line in source.split_inclusive('\n') {
        let end = line_start + line.len();
        let line_code = &code[line_start..end];
        let starts_in_string = in_string;
        in_string ^= line_code.iter().filter(|&&c| c == b'"').count() % 2 == 1;
        let Some(first) = line_code.iter().position(|c| !c.is_ascii_whitespace()) else {
            line_start = end;
            continue;
        };
        let indent = line.len() - line.trim_start().len();
        if indentation_tells && !starts_in_string {
            // A block closed at the end of a line deeper than its own is
            // written Lisp-style, unless the next line is still as deep.
            if let Some((open, closer)) = closed_early.take() {
                if indent > open.line_indent {
                    return Some(closed_too_soon(
                        source,
                        code,
                        &open,
                        closer,
                        line_start + first,
                    ));
                }
            }
            for open in stack.iter_mut().filter(|open| open.block.is_none()) {
                open.block = Some(indent > open.line_indent);
            }
            if let Some(open) = left_open_at(&stack, &line_code[first..], indent) {
                let (line_number, _) = line_col_of_offset(source, line_start);
                return Some(suspect(
                    source,
                    code,
                    open,
                    line_start + first,
                    &format!("still open where line {line_number} begins"),
                ));
            }
        }
        for (k, &c) in line_code.iter().enumerate().skip(first) {
            let offset = line_start + k;
            match c {
                b'(' | b'[' | b'{' => stack.push(Open {
                    bracket: c,
                    offset,
                    line_start,
                    line_indent: indent,
                    ends_line: line_code[k + 1..].iter().all(u8::is_ascii_whitespace),
                    block: None,
                }),
                b')' | b']' | b'}' => match stack.pop() {
                    Some(open) if closer_of(open.bracket) == c => {
                        if open.block == Some(true)
                            && indent > open.line_indent
                            && closed_early.is_none()
                        {
                            closed_early = Some((open, offset));
                        }
                    }
                    Some(open) => {
                        // A closer missing before this one, or this one
                        // too many: the brackets alone cannot tell.
                        let (line, col) = line_col_of_offset(source, offset);
                        let mut wrong_kind = suspect(
                            source,
                            code,
                            &open,
                            offset,
                            &format!(
                                "still open where the `{}` at {line}:{col} closes",
                                c as char
                            ),
                        );
                        wrong_kind.hint.insert_str(
                            wrong_kind.hint.len() - 1,
                            &format!(", or is that `{}` one too many?", c as char),
                        );
                        return Some(wrong_kind);
                    }
                    None => {
                        let (line, col) = line_col_of_offset(source, offset);
                        return Some(Suspect {
                            shows_at: offset,
                            hint: format!(
                                " (the `{}` at {line}:{col} closes no bracket: is it one too many?)",
                                c as char
                            ),
                        });
                    }
                },
                _ => {}
            }
        }
        line_start = end;
    }
    let open = stack.last()?;
    let mut at_end = suspect(source, code, open, source.len(), "never closed");
    at_end.hint = at_end
        .hint
        .replacen(" (is", " (the file ends here: is it cut short, or is", 1);
    Some(at_end)
}

/// The bracket of `stack` (innermost first) that a line whose code starts
/// with `line_code`, indented by `indent`, shows left open: a block whose
/// line is no shallower than this one, or a bracket opened within its line
/// whose next line is no deeper, unless the line starts by closing it
/// (`]),` closes the innermost two; a bracket opened within its line only
/// together with a block it opened last on that line).
fn left_open_at<'a>(stack: &'a [Open], line_code: &[u8], indent: usize) -> Option<&'a Open> {
    let mut inner_line = None;
    let closed_first = line_code
        .iter()
        .take_while(|c| matches!(c, b')' | b']' | b'}'))
        .zip(stack.iter().rev())
        .take_while(|(&c, open)| {
            let closes = c == closer_of(open.bracket)
                && (open.block == Some(true)
                    || open.ends_line
                    || inner_line == Some(open.line_start));
            inner_line = Some(open.line_start);
            closes
        })
        .count();
    stack[..stack.len() - closed_first]
        .iter()
        .rev()
        .find(|open| match open.block {
            Some(true) => indent <= open.line_indent,
            Some(false) => !open.ends_line,
            None => false,
        })
}

/// Whether the file writes the contents of its blocks one level deeper
/// than the line that opens them: some bracket ends its line and the next
/// line of code is indented deeper (else indentation tells nothing).
fn indents_blocks(source: &str, code: &[u8]) -> bool {
    let lines = code_lines(source, code);
    let indent = |line: &str| line.len() - line.trim_start().len();
    lines.windows(2).any(|pair| {
        let (at, line) = pair[0];
        let opens_block = code[at..at + line.len()]
            .iter()
            .rev()
            .find(|c| !c.is_ascii_whitespace())
            .is_some_and(|c| matches!(c, b'(' | b'[' | b'{'));
        opens_block && indent(pair[1].1) > indent(line)
    })
}

/// Whether some lines of code are indented with tabs and others with
/// spaces (their depths then depend on the editor's tab width).
fn mixes_tabs_and_spaces(source: &str, code: &[u8]) -> bool {
    let leading = |line: &str| line[..line.len() - line.trim_start().len()].to_string();
    let lines = code_lines(source, code);
    let tabs = lines.iter().any(|(_, line)| leading(line).contains('\t'));
    let spaces = lines.iter().any(|(_, line)| leading(line).contains(' '));
    tabs && spaces
}

/// The lines of `source` that hold code (not only whitespace and
/// comments), with their byte offsets.
fn code_lines<'a>(source: &'a str, code: &[u8]) -> Vec<(usize, &'a str)> {
    source
        .split_inclusive('\n')
        .scan(0, |start, line| {
            let at = *start;
            *start += line.len();
            Some((at, line))
        })
        .filter(|(at, line)| {
            code[*at..*at + line.len()]
                .iter()
                .any(|c| !c.is_ascii_whitespace())
        })
        .collect()
}

/// The hint for a closing bracket at `closer` that closes the block
/// `open` while the line beginning at `shows_at` is indented as inside it.
fn closed_too_soon(
    source: &str,
    code: &[u8],
    open: &Open,
    closer: usize,
    shows_at: usize,
) -> Suspect {
    let (line, col) = line_col_of_offset(source, closer);
    let (open_line, open_col) = line_col_of_offset(source, open.offset);
    let (next_line, _) = line_col_of_offset(source, shows_at);
    let what = label(code, open.offset).map_or(String::new(), |label| format!(" of {label}"));
    Suspect {
        shows_at,
        hint: format!(
            " (is the `{}` at {line}:{col} one too many? it closes the `{}`{what} at \
             {open_line}:{open_col}, yet line {next_line} is indented as inside it)",
            closer_of(open.bracket) as char,
            open.bracket as char,
        ),
    }
}

/// The hint for `open`, left open, which shows at `shows_at`: what is
/// missing, which bracket, and `where_seen`.
fn suspect(source: &str, code: &[u8], open: &Open, shows_at: usize, where_seen: &str) -> Suspect {
    let (line, col) = line_col_of_offset(source, open.offset);
    let closer = closer_of(open.bracket) as char;
    let bracket = open.bracket as char;
    let what = match label(code, open.offset) {
        Some(label) => format!("the `{bracket}` of {label}"),
        None => format!("the `{bracket}`"),
    };
    let missing = if open.ends_line {
        format!("is a `{closer}` missing?")
    } else {
        format!("is a `{closer}` missing on line {line}?")
    };
    Suspect {
        shows_at,
        hint: format!(" ({missing} {what} at {line}:{col} is {where_seen})"),
    }
}

/// What a bracket at `offset` of the blanked `code` opens, in words:
/// `` `Material(` `` for a struct's, `` field `inclusions` `` for a field's
/// list or map, else None.
fn label(code: &[u8], offset: usize) -> Option<String> {
    // Blanking keeps the text's bytes outside comments and strings, and
    // writes whole characters as spaces inside them: still UTF-8.
    let code = std::str::from_utf8(code).ok()?;
    let before = code[..offset].trim_end();
    let word = |text: &str| -> String {
        let start = text
            .char_indices()
            .rev()
            .find(|(_, c)| !(c.is_ascii_alphanumeric() || *c == '_'))
            .map_or(0, |(i, c)| i + c.len_utf8());
        text[start..].to_string()
    };
    if code.as_bytes()[offset] == b'(' {
        let name = word(before);
        if !name.is_empty() {
            return Some(format!("`{name}(`"));
        }
    }
    let field = word(before.strip_suffix(':')?.trim_end());
    (!field.is_empty()).then(|| format!("field `{field}`"))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GEM: &str = "Gem(
    name: \"g\", // a (note
    materials: {
        \"glass\": Material(layers: [Layer(ior: 1.53)], base: Black),
        \"copper\": Material(layers: [], base: Conductor(metal: \"copper\")),
    },
    maps: {
        \"tiles\": SurfaceMap(cell_size: 0.1, entries: [
            (material: \"glass\"),
        ]),
    },
    surface: \"glass\",
    body: Translucent(
        ior: 1.53,
        inclusions: [
            Inclusions(shape: Triangle, material: \"copper\"),
        ],
    ),
)
";

    /// The hint for an error at the start of line `line` (1-based).
    fn hint_at_line(source: &str, line: usize) -> Option<String> {
        let offset: usize = source
            .split_inclusive('\n')
            .take(line - 1)
            .map(str::len)
            .sum();
        let indent = source[offset..].len() - source[offset..].trim_start().len();
        open_bracket_hint(source, offset + indent, false)
    }

    #[test]
    fn a_whole_file_has_no_suspect() {
        for line in 1..=19 {
            assert_eq!(hint_at_line(GEM, line), None, "line {line}");
        }
        assert_eq!(open_bracket_hint(GEM, GEM.len(), true), None);
        // Nor any built-in recipe or material, nor the repository's other
        // RON files (scenes, jobs, examples), read to their ends.
        let library = crate::recipe::library::BUILTIN_GEMS
            .iter()
            .map(|(_, text)| text.to_string())
            .chain(
                crate::recipe::library::builtin_material_names().map(|name| {
                    crate::recipe::library::builtin_material_source(name)
                        .unwrap()
                        .to_string()
                }),
            );
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut files: Vec<String> = library.collect();
        for folder in [
            "bench",
            "bench/suite",
            "examples",
            "examples/farm",
            "gem-recipes",
            "gem-recipes/materials",
            "gem-recipes/scenes",
        ] {
            let Ok(entries) = std::fs::read_dir(root.join(folder)) else {
                continue;
            };
            files.extend(entries.flatten().filter_map(|entry| {
                let path = entry.path();
                (path.extension()? == "ron").then(|| std::fs::read_to_string(path).unwrap())
            }));
        }
        assert!(files.len() > 40, "{} files", files.len());
        for text in &files {
            assert_eq!(open_bracket_hint(text, text.len(), true), None, "{text}");
        }
        // Nor one written flat, without indentation.
        let flat = "Gem(\nname: \"g\",\nmaterials: {\"a\": M(x: 1),\n\"b\": M(x: 2)},\n)";
        assert_eq!(open_bracket_hint(flat, flat.len(), true), None);
    }

    #[test]
    fn layouts_with_every_bracket_closed_get_no_hint_for_an_error_elsewhere() {
        // Each is valid as far as brackets go; the error is on its last
        // line (a wrong value, say), so nothing is to be said of brackets.
        let layouts = [
            // The first field on the opening line, the closer on its own.
            "Gem(\n    materials: {\n        \"a\": Material(layers: [],\n            base: Black,\n        ),\n    },\n    seed: x,\n)",
            // Top-level fields not indented, inner blocks indented.
            "Gem(\nmaterials: {\n    \"a\": M(),\n},\nseed: x,\n)",
            // Tabs on some lines, spaces on others.
            "Gem(\n\tmaterials: {\n        \"a\": M(),\n\t},\n    seed: x,\n)",
            // A string over two lines, a nested comment holding a bracket.
            "Gem(\n    description: \"two\nlines\",\n    /* a /* ( */ b */\n    seed: x,\n)",
            // Non-ASCII text in comments, strings and before brackets.
            "Gem( // ³\n    naïve(a: \"é\"),\n    seed: x,\n)",
        ];
        for text in layouts {
            let error = text.rfind("x,").unwrap();
            assert_eq!(open_bracket_hint(text, error, false), None, "{text}");
        }
    }

    #[test]
    fn a_bracket_is_named_by_its_code_not_by_a_comment_before_it() {
        let text = "Gem(\n    inclusions: [\n        // Triangular crystals ³\n        (shape: Triangle,\n        (shape: Disc),\n    ],\n)";
        let hint = open_bracket_hint(text, text.find("(shape: Disc").unwrap(), false).unwrap();
        assert!(hint.contains("the `(` at 4:9 is still open"), "{hint}");
        let text = "Gem(\n    absorption: // per mm³\n        (0.05, 0.15, 0.3,\n    seed: 1,\n)";
        let hint = open_bracket_hint(text, text.find("seed").unwrap(), false).unwrap();
        assert!(
            hint.contains("the `(` of field `absorption` at 3:9"),
            "{hint}"
        );
    }

    #[test]
    fn a_struct_left_open_on_its_line_is_named_where_the_next_line_begins() {
        let text = GEM.replace("base: Black),", "base: Black,");
        assert_eq!(
            hint_at_line(&text, 5).as_deref(),
            Some(" (is a `)` missing on line 4? the `(` of `Material(` at 4:26 is still open where line 5 begins)")
        );
        // Not for an error on a line before the one where it shows.
        assert_eq!(hint_at_line(&text, 4), None);
    }

    #[test]
    fn a_block_left_open_is_named_where_a_line_as_shallow_as_its_own_begins() {
        let text = GEM.replace("        ],\n", "        ,\n");
        assert_eq!(
            hint_at_line(&text, 17).as_deref(),
            Some(" (is a `]` missing? the `[` of field `inclusions` at 15:21 is still open where line 17 begins)")
        );
        let text = GEM.replacen("    },\n", "    ,\n", 1);
        assert!(hint_at_line(&text, 6)
            .unwrap()
            .contains("the `{` of field `materials` at 3:16"));
    }

    #[test]
    fn a_bracket_of_another_kind_and_one_too_many_are_named() {
        let text = GEM.replace("[Layer(ior: 1.53)]", "[Layer(ior: 1.53]");
        let hint = hint_at_line(&text, 5).unwrap();
        assert!(
            hint.contains(
                "the `(` of `Layer(` at 4:41 is still open where the `]` at 4:51 closes, or is that \
                 `]` one too many?)"
            ),
            "{hint}"
        );
        let text = GEM.replace("ior: 1.53,", "ior: 1.53),");
        let hint = hint_at_line(&text, 15).unwrap();
        assert!(
            hint.contains("is the `)` at 14:18 one too many? it closes the `(` of `Translucent(` at 13:22, yet line 15 is indented as inside it"),
            "{hint}"
        );
        // An error at that very bracket has RON's own hint about it; one
        // after it names it.
        let text = format!("{GEM})");
        assert_eq!(open_bracket_hint(&text, text.len() - 1, false), None);
        let hint = open_bracket_hint(&text, text.len(), true).unwrap();
        assert!(hint.contains("`)` at 20:1 closes no bracket"), "{hint}");
        // A list closed at the end of its last item's line, Lisp-style.
        let text = GEM.replace("\"copper\"),\n        ],", "\"copper\")],");
        assert_eq!(open_bracket_hint(&text, text.len(), true), None);
    }

    #[test]
    fn a_file_that_ends_open_names_the_bracket_and_a_string_its_quote() {
        let text = GEM.trim_end().strip_suffix(')').unwrap();
        let hint = open_bracket_hint(text, text.len(), true).unwrap();
        assert!(
            hint.contains(
                "the file ends here: is it cut short, or is a `)` missing? the `(` of `Gem(` at 1:4 \
                 is never closed"
            ),
            "{hint}"
        );
        let text = GEM.replace("name: \"g\",", "name: \"g,");
        let hint = hint_at_line(&text, 3).unwrap();
        assert!(
            hint.contains("the string opened at 2:11 runs on past the end of its line"),
            "{hint}"
        );
    }
}
