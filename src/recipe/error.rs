//! Errors in recipes and material files, always with the file and, where
//! known, the line and column: `file:line:col: message`.

use std::fmt;

use crate::recipe::brackets::open_bracket_hint;
pub(crate) use crate::recipe::ron_text::blank_comments_and_strings;
pub use crate::recipe::ron_text::line_col_of_offset;

/// A problem with a user's (or a built-in) RON file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RecipeError {
    /// The file (or `builtin:NAME` for embedded files).
    pub path: String,
    /// 1-based line and column, when the problem has a place in the text.
    pub position: Option<(usize, usize)>,
    /// What is wrong and what is allowed.
    pub message: String,
    /// Further problems found in the same file by the same pass (every
    /// unknown name a recipe uses), written after this one.
    pub further: Vec<RecipeError>,
}

impl RecipeError {
    /// An error with a position in the file.
    pub fn at(path: &str, line: usize, col: usize, message: impl Into<String>) -> Self {
        RecipeError {
            path: path.to_string(),
            position: Some((line, col)),
            message: message.into(),
            further: Vec::new(),
        }
    }

    /// An error about the whole file (unreadable, missing).
    pub fn whole_file(path: &str, message: impl Into<String>) -> Self {
        RecipeError {
            path: path.to_string(),
            position: None,
            message: message.into(),
            further: Vec::new(),
        }
    }

    /// `others` and then `one` as one error, file by file in the order
    /// they first appear and in each file in the order written (those
    /// without a place last): the first, with the others, each once, as
    /// its [`RecipeError::further`].
    pub(crate) fn gathered(one: RecipeError, mut others: Vec<RecipeError>) -> Self {
        others.push(one);
        let mut files: Vec<String> = Vec::new();
        for e in &others {
            if !files.contains(&e.path) {
                files.push(e.path.clone());
            }
        }
        others.sort_by_key(|e| {
            let file = files.iter().position(|path| *path == e.path);
            (file, e.position.unwrap_or((usize::MAX, usize::MAX)))
        });
        others.dedup();
        // Not empty: it holds `one`.
        let mut first = others.remove(0);
        first.further.extend(others);
        first
    }

    /// Every one of `errors` as one, or None when there are none: file by
    /// file in the order they first appear and in each file in the order
    /// written (those without a place last), the first with the others,
    /// each once, as its [`RecipeError::further`].
    pub fn all(mut errors: Vec<RecipeError>) -> Option<Self> {
        let one = errors.pop()?;
        Some(Self::gathered(one, errors))
    }

    /// An error at the first place `needle` is written in `source` as code
    /// (`find_in_code`: not in a comment; a quoted needle as a whole string
    /// literal, any other not inside one), else at its first occurrence
    /// anywhere, else about the whole file; for problems found after parsing.
    pub fn at_text(path: &str, source: &str, needle: &str, message: impl Into<String>) -> Self {
        let place = find_in_code(source, needle)
            .map(|offset| line_col_of_offset(source, offset))
            .or_else(|| find_position(source, needle, 0));
        match place {
            Some((line, col)) => RecipeError::at(path, line, col, message),
            None => RecipeError::whole_file(path, message),
        }
    }
}

/// How many of an error's [`RecipeError::further`] problems its message
/// shows (a scene of 1000 stones, each naming a missing recipe, says so in
/// a screenful).
const MAX_FURTHER_SHOWN: usize = 19;

impl fmt::Display for RecipeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.position {
            Some((line, col)) => write!(f, "{}:{}:{}: ", self.path, line, col)?,
            None => write!(f, "{}: ", self.path)?,
        }
        // A control character quoted from the file (a NUL in a name) is
        // written as its escape, not sent to the terminal.
        for c in self.message.chars() {
            match c {
                '\n' | '\t' => write!(f, "{c}")?,
                c if c.is_control() => write!(f, "{}", c.escape_unicode())?,
                c => write!(f, "{c}")?,
            }
        }
        for more in self.further.iter().take(MAX_FURTHER_SHOWN) {
            write!(f, "\n{more}")?;
        }
        if self.further.len() > MAX_FURTHER_SHOWN {
            let left = self.further.len() - MAX_FURTHER_SHOWN;
            write!(f, "\n{}: {left} more problems like these", self.path)?;
        }
        Ok(())
    }
}

impl std::error::Error for RecipeError {}

/// 1-based line and column of the `nth` (0-based) occurrence of `needle`.
pub(crate) fn find_position(source: &str, needle: &str, nth: usize) -> Option<(usize, usize)> {
    let offset = source.match_indices(needle).nth(nth)?.0;
    Some(line_col_of_offset(source, offset))
}

/// Byte offset of the first place `needle` is written in RON `source` as
/// code: never inside a comment; a needle in quotes (`"gold"`) only as a
/// whole string literal, and preferably one that is a value (a reference
/// to the name) rather than a map key (`"gold": …`, its definition); any
/// other needle (`surface`) only outside string literals.
pub(crate) fn find_in_code(source: &str, needle: &str) -> Option<usize> {
    let code = blank_comments_and_strings(source);
    let quoted = needle.len() >= 2 && needle.starts_with('"') && needle.ends_with('"');
    let mut key = None;
    for (i, _) in source.match_indices(needle) {
        let span = &code[i..i + needle.len()];
        if !quoted {
            if span == needle.as_bytes() {
                return Some(i);
            }
            continue;
        }
        // Both quotes are code and everything between them was blanked:
        // the literal itself, not a quote closing an earlier string.
        let inner = &needle.as_bytes()[1..needle.len() - 1];
        let literal = span[0] == b'"'
            && span[span.len() - 1] == b'"'
            && span[1..span.len() - 1]
                .iter()
                .zip(inner)
                .all(|(c, n)| *c == b' ' || *n == b' ');
        if !literal {
            continue;
        }
        let after = code[i + needle.len()..]
            .iter()
            .find(|c| !c.is_ascii_whitespace());
        if after == Some(&b':') {
            key.get_or_insert(i);
        } else {
            return Some(i);
        }
    }
    key
}

/// Byte offset of the `nth` (0-based) place `needle` is written in RON
/// `source` as code: outside comments and string literals.
pub(crate) fn nth_in_code(source: &str, needle: &str, nth: usize) -> Option<usize> {
    let code = blank_comments_and_strings(source);
    source
        .match_indices(needle)
        .filter(|(i, _)| &code[*i..*i + needle.len()] == needle.as_bytes())
        .nth(nth)
        .map(|(i, _)| i)
}

/// The name of the field whose value starts at or before (line, col): the
/// last `identifier:` in the text up to that point, unless the item that
/// field belongs to closed before it (a stray bracket after the last
/// field: naming that field would send a reader to the wrong place). RON's
/// type errors ("Expected float") do not name the field; this recovers it.
pub(crate) fn field_before(source: &str, line: usize, col: usize) -> Option<String> {
    let mut offset = 0;
    for (k, text) in source.split_inclusive('\n').enumerate() {
        if k + 1 == line {
            offset += text
                .char_indices()
                .nth(col.saturating_sub(1))
                .map_or(text.len(), |(i, _)| i);
            break;
        }
        offset += text.len();
    }
    let before = &source[..offset.min(source.len())];
    // Drop comments so that words in them are not taken for fields.
    let cleaned: String = before
        .lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let colon = cleaned.rfind(':')?;
    if closes_its_item(&cleaned[colon + 1..]) {
        return None;
    }
    let name: String = cleaned[..colon]
        .trim_end()
        .chars()
        .rev()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    (!name.is_empty()).then_some(name)
}

/// Whether `text` (what follows a field's colon) closes more brackets than
/// it opens, outside strings: the item holding the field has ended.
fn closes_its_item(text: &str) -> bool {
    let (mut depth, mut in_string, mut escaped) = (0i32, false, false);
    for c in text.chars() {
        if in_string {
            match c {
                _ if escaped => escaped = false,
                '\\' => escaped = true,
                '"' => in_string = false,
                _ => {}
            }
            continue;
        }
        match c {
            '"' => in_string = true,
            '(' | '[' | '{' => depth += 1,
            ')' | ']' | '}' => {
                depth -= 1;
                if depth < 0 {
                    return true;
                }
            }
            _ => {}
        }
    }
    false
}

/// The offset just past the RON attribute `#![…]` (whitespace allowed
/// between `#`, `!` and `[`) that starts at `start` in `code` (the text
/// with comments and strings blanked, so that their brackets do not
/// count); None when none starts there or it is never closed.
fn attribute_end(code: &[u8], start: usize) -> Option<usize> {
    let skip = |k: usize| {
        k + code[k.min(code.len())..]
            .iter()
            .take_while(|c| c.is_ascii_whitespace())
            .count()
    };
    let bang = skip(start + 1);
    let open = skip(bang + 1);
    if code.get(bang) != Some(&b'!') || code.get(open) != Some(&b'[') {
        return None;
    }
    let mut depth = 0usize;
    for (k, &c) in code.iter().enumerate().skip(open) {
        match c {
            b'[' | b'(' => depth += 1,
            b']' | b')' => {
                depth = depth.checked_sub(1)?;
                if depth == 0 {
                    return (c == b']').then_some(k + 1);
                }
            }
            _ => {}
        }
    }
    None
}

/// Byte offset of the first character of `text` that is not whitespace, a
/// `//` or `/* */` comment (nested, as RON reads them), a byte-order mark
/// or a RON `#![enable(…)]` attribute; an attribute left open is code, for
/// the parser to place its error there.
pub fn first_code_offset(text: &str) -> usize {
    const BYTE_ORDER_MARK: &[u8] = "\u{feff}".as_bytes();
    let code = blank_comments_and_strings(text);
    let mut i = 0;
    while i < code.len() {
        if code[i].is_ascii_whitespace() {
            i += 1;
        } else if code[i..].starts_with(BYTE_ORDER_MARK) {
            i += BYTE_ORDER_MARK.len();
        } else if let Some(end) = (code[i] == b'#').then(|| attribute_end(&code, i)).flatten() {
            i = end;
        } else {
            break;
        }
    }
    i
}

/// RON's `message` for an error at (line, col) of `source`, with plainer
/// words for its type errors (what to write); where a closing bracket
/// stands at an error outside any field's value, or text follows the
/// recipe's end, that a bracket may be one too many; where a bracket or a
/// string opened before the error looks left open, which one
/// ([`open_bracket_hint`]); else, where only whitespace and comments
/// follow, that the file ends there (RON's own message, "expected `(`",
/// does not say so).
pub(crate) fn with_ron_hints(mut message: String, source: &str, line: usize, col: usize) -> String {
    for (ron_says, allowed) in [
        ("Expected float", "a number such as 1.5, without quotes"),
        (
            "Expected integer",
            "a whole number such as 4, without quotes",
        ),
        ("Expected string", "a name in double quotes"),
        ("Expected option", "`Some(…)` around the value, or `None`"),
    ] {
        if message.ends_with(ron_says) {
            message.push_str(&format!("; allowed: {allowed}"));
        }
    }
    let line_start = line_start_offset(source, line);
    let offset = source[line_start.min(source.len())..]
        .char_indices()
        .nth(col.saturating_sub(1))
        .map_or(source.len(), |(i, _)| line_start + i);
    let rest = &source[offset.min(source.len())..];
    let at_end = first_code_offset(rest) >= rest.len();
    // A bracket or a quote left open before the error, which RON's
    // message does not name; it says more than the guesses below.
    let left_open = open_bracket_hint(source, offset, at_end);
    // RON expected something else where a closing bracket stands, outside
    // any field's value (a field's own error names the field): one too
    // many, or of the wrong kind; RON says only what it expected.
    let closer = rest.chars().next().filter(|c| matches!(c, ')' | ']' | '}'));
    if let Some(c) = closer.filter(|_| message.starts_with("Expected") && left_open.is_none()) {
        message.push_str(&format!(
            " (is this `{c}` one too many, or the wrong kind of bracket?)"
        ));
    }
    // Whole numbers out of their type's range, or written with a fraction
    // or an exponent.
    if message.ends_with("Integer is out of bounds") {
        message
            .push_str("; allowed: a whole number from 0, without a sign, within the field's range");
    }
    if message.contains("for base 10 integers") {
        message.push_str(
            "; allowed: a whole number written in digits only (no point, exponent or sign)",
        );
    }
    // A `#` opens RON's attributes (`#![enable(…)]`): at a file's start
    // it is more likely a file of another kind (Markdown, a shell script).
    if message.contains("#![enable(") && line == 1 {
        message.push_str(
            " (is this a RON file? a recipe starts with `Gem(`, `Material(`, `Scene(` or `Job(`)",
        );
    }
    // A whole number's field given a fraction: RON reads the whole part
    // and then stops at the point.
    let mut after = rest.chars();
    if message.ends_with("Expected comma")
        && after.next() == Some('.')
        && after.next().is_some_and(|c| c.is_ascii_digit())
    {
        message.push_str("; allowed: a whole number such as 4, without a fraction");
    }
    // RON's advice for text it cannot read as a name ("try the raw
    // identifier `r#--` instead") is for Rust's raw identifiers, never
    // what a recipe needs: say what stands there instead.
    if let Some(at) = message.find("Found invalid std identifier \"") {
        let found = &message[at + "Found invalid std identifier \"".len()..];
        let found = found.split('"').next().unwrap_or_default().to_string();
        message.truncate(at);
        message.push_str(&format!(
            "found `{found}` where a field name or a value was expected"
        ));
    }
    // A comment in another language's syntax (`# …`, `-- …`) where RON
    // stopped: RON's are `// …` and `/* … */`.
    let other_comment = ["#", "--"]
        .into_iter()
        .find(|mark| rest.trim_start().starts_with(mark) && !rest.trim_start().starts_with("#!"));
    if let Some(mark) = other_comment {
        message.push_str(&format!(
            " (is `{mark}` a comment? RON's comments are `// …` and `/* … */`)"
        ));
    }
    // `0x2`, `0b1`, `0o7` where a number with a fraction belongs: RON reads
    // these forms for whole numbers only, so it reads the `0` and stops
    // at the letter (or a range check refuses the 0).
    let radix_number = radix_number_at(source, offset)
        .filter(|&(_, start)| offset == start + 1 || message.contains("` = 0 is out of range"));
    if let Some((number, _)) = radix_number {
        message.push_str(&format!(
            " (`{number}` is read as 0 followed by `{}`: this field takes a number in \
             decimal digits, such as 1.5)",
            &number[1..]
        ));
    }
    if message == "Non-whitespace trailing characters" {
        message.push_str(
            " after the end of the recipe (is a closing bracket before it one too many?)",
        );
    }
    if let Some((at_col, c)) = stray_character_on_line(source, line) {
        message.push_str(&format!(
            "; line {line} holds {} at column {at_col}, which RON does not read as \
             part of a recipe: delete it and type the text again",
            character_name(c)
        ));
    }
    match left_open {
        Some(hint) => message.push_str(&hint),
        None if at_end => message.push_str(
            " (the file ends here: is it cut short, or is a closing `)`, `]` or `}` missing?)",
        ),
        None => {}
    }
    message
}

/// The word of letters, digits, `_` and `.` around byte `offset` of
/// `source` (the character there or just before it), when it is a whole
/// number in RON's hexadecimal, binary or octal form (`0x…`, `0b…`, `0o…`),
/// and the byte offset where it starts.
fn radix_number_at(source: &str, offset: usize) -> Option<(&str, usize)> {
    let bytes = source.as_bytes();
    let in_word = |b: u8| b.is_ascii_alphanumeric() || b == b'_' || b == b'.';
    let mut start = offset.min(bytes.len());
    while start > 0 && in_word(bytes[start - 1]) {
        start -= 1;
    }
    let end = (start..bytes.len())
        .find(|&i| !in_word(bytes[i]))
        .unwrap_or(bytes.len());
    let word = &source[start..end];
    let digits_after = |prefix: &str, digit: fn(&u8) -> bool| {
        word.strip_prefix(prefix)
            .is_some_and(|rest| !rest.is_empty() && rest.bytes().all(|b| b == b'_' || digit(&b)))
    };
    let radix = [
        ("0x", u8::is_ascii_hexdigit as fn(&u8) -> bool),
        ("0b", |b| matches!(b, b'0' | b'1')),
        ("0o", |b| matches!(b, b'0'..=b'7')),
    ];
    radix
        .into_iter()
        .any(|(prefix, digit)| {
            digits_after(prefix, digit) || digits_after(&prefix.to_uppercase(), digit)
        })
        .then_some((word, start))
}

/// The byte offset where line `line` (1-based) of `source` starts (the
/// text's length past its last line).
fn line_start_offset(source: &str, line: usize) -> usize {
    source
        .split_inclusive('\n')
        .take(line.saturating_sub(1))
        .map(str::len)
        .sum()
}

/// The first character outside the ASCII set, or an ASCII control
/// character other than a tab or a line end, on line `line` (1-based) of
/// `source`, outside comments and string literals, and its column: RON
/// reads names, numbers and brackets in printable ASCII only, so such a
/// character (often invisible, pasted from a web page or a word
/// processor, or a NUL from a damaged file) stops the parse there or
/// splits a name in two.
fn stray_character_on_line(source: &str, line: usize) -> Option<(usize, char)> {
    let code = blank_comments_and_strings(source);
    let line_start = line_start_offset(source, line);
    let line_end = source[line_start.min(source.len())..]
        .find('\n')
        .map_or(source.len(), |end| line_start + end);
    let stray = |b: u8| !b.is_ascii() || (b.is_ascii_control() && !b"\t\r\n".contains(&b));
    let offset = (line_start..line_end).find(|&i| stray(code[i]))?;
    let c = source[offset..].chars().next()?;
    Some((source[line_start..offset].chars().count() + 1, c))
}

/// A character as a message names it: the invisible ones and the spaces
/// that look like a space by name, every one by its code point.
fn character_name(c: char) -> String {
    let code = format!("U+{:04X}", u32::from(c));
    match c {
        '\u{a0}' | '\u{202f}' => format!("a no-break space ({code})"),
        '\u{200b}' => format!("a zero-width space ({code})"),
        '\u{200c}' | '\u{200d}' => format!("a zero-width joiner ({code})"),
        '\u{2060}' => format!("a word joiner ({code})"),
        '\u{feff}' => format!("a byte-order mark ({code})"),
        '\u{2000}'..='\u{200a}' | '\u{205f}' | '\u{3000}' => {
            format!("a typographic space ({code})")
        }
        '\u{2018}' | '\u{2019}' | '\u{201c}' | '\u{201d}' => {
            format!("a curly quote ({code}, where RON takes `\"`)")
        }
        '\u{2212}' | '\u{2013}' | '\u{2014}' => {
            format!("a typographic minus or dash ({code}, where RON takes `-`)")
        }
        '\0' => format!("a NUL byte ({code})"),
        c if c.is_control() => format!("a control character ({code})"),
        _ => format!("`{c}` ({code})"),
    }
}

/// A note for a path that was not found and is written with `\\` between
/// its folders (a Windows habit; lapidary reads `/` on every system), else
/// nothing.
pub fn folder_separator_hint(written: &str) -> &'static str {
    if written.contains('\\') {
        " (write `/` between folders, not `\\`)"
    } else {
        ""
    }
}

/// The closest of `candidates` to `word` by edit distance, if close enough
/// to be a likely typo.
pub fn did_you_mean<'a>(
    word: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (strsim::damerau_levenshtein(word, c), c))
        // Two edits make another word of a short one (`Foo` → `Job`): one
        // for names of up to four letters.
        .filter(|(d, c)| *d <= if c.len() <= 4 { 1 } else { 2.max(c.len() / 3) })
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_one_based() {
        let src = "ab\ncd: 1\n";
        assert_eq!(find_position(src, "cd", 0), Some((2, 1)));
        assert_eq!(line_col_of_offset(src, 0), (1, 1));
    }

    #[test]
    fn field_before_finds_the_last_field_name_ignoring_comments() {
        let src = "Layer(\n  ior: \"x\", // note: here\n";
        assert_eq!(field_before(src, 2, 8).as_deref(), Some("ior"));
    }

    #[test]
    fn field_before_names_no_field_of_an_item_already_closed() {
        // A stray bracket after a light: the light's last field is not the
        // culprit.
        let src = "lights: [\n  Point(at: (1, 2, 3), intensity: (7, 7, 7)),\n  ),\n]";
        assert_eq!(field_before(src, 3, 3), None);
        // Brackets inside a string do not count; a value still open does.
        let src = "Gem(description: \"a (note\", seed: (1, 2 x";
        assert_eq!(field_before(src, 1, 41).as_deref(), Some("seed"));
    }

    #[test]
    fn find_in_code_skips_comments_strings_and_definitions() {
        let src = "// surface: \"gold\"\nGem(description: \"a surface\", /* \"gold\" */\n  materials: {\"gold\": M()}, surface: \"gold\")";
        let code_surface = src.rfind("surface").unwrap();
        assert_eq!(find_in_code(src, "surface"), Some(code_surface));
        // The value `"gold"`, not the comments' nor the key `"gold":`.
        assert_eq!(
            find_in_code(src, "\"gold\""),
            Some(src.rfind("\"gold\"").unwrap())
        );
        // Only a key: the key.
        let defined = "{\"tiles\" : A(), \"x\": B(\"y\")}";
        assert_eq!(find_in_code(defined, "\"tiles\""), Some(1));
        // A quote closing a string is not a literal of the name.
        assert_eq!(find_in_code("(a: \"b\"c\")", "\"c\""), None);
        assert_eq!(find_in_code("// only here: gold", "gold"), None);
        let e = RecipeError::at_text("f.ron", "// gold\nx: gold", "gold", "m");
        assert_eq!(e.position, Some((2, 4)));
        // Nowhere as code: the first occurrence, then the whole file.
        let e = RecipeError::at_text("f.ron", "// gold\n", "gold", "m");
        assert_eq!(e.position, Some((1, 4)));
        assert_eq!(
            RecipeError::at_text("f.ron", "", "gold", "m").position,
            None
        );
    }

    #[test]
    fn a_character_outside_ascii_in_code_is_named_with_its_column() {
        let text = "Gem(\n    se\u{200b}ed: 1, // caf\u{e9}\n    name: \"\u{e9}\",\n)";
        assert_eq!(stray_character_on_line(text, 2), Some((7, '\u{200b}')));
        // In a comment or a string it is text, not code.
        assert_eq!(stray_character_on_line(text, 3), None);
        assert_eq!(stray_character_on_line(text, 1), None);
        let message = with_ron_hints("Expected colon".into(), text, 2, 5);
        assert!(
            message.contains("line 2 holds a zero-width space (U+200B) at column 7"),
            "{message}"
        );
        assert!(character_name('\u{2212}').contains("where RON takes `-`"));
        assert_eq!(character_name('\u{d7}'), "`\u{d7}` (U+00D7)");
    }

    #[test]
    fn code_starts_after_nested_comments_and_closed_attributes_only() {
        // RON's block comments nest: the code starts at `Gem(`, not at `c`.
        let nested = "/* a /* b */ c */\nGem(surface: \"gold\")";
        assert_eq!(first_code_offset(nested), nested.find("Gem(").unwrap());
        let attribute = "#![enable(implicit_some)]\n// note\nGem()";
        assert_eq!(
            first_code_offset(attribute),
            attribute.find("Gem(").unwrap()
        );
        // An attribute left open is code (the parser then says where),
        // not a file of comments only.
        assert_eq!(first_code_offset("#![enable(implicit_some)\nGem()"), 0);
        // Space after `#` and `!`, a bracket in a string: still attributes.
        for attribute in ["#! [enable(implicit_some)]", "#![type = \"gem (v1\"]"] {
            let text = format!("{attribute}\nGem()");
            assert_eq!(
                first_code_offset(&text),
                text.find("Gem(").unwrap(),
                "{text}"
            );
        }
        assert_eq!(
            first_code_offset(" /* never closed"),
            " /* never closed".len()
        );
    }

    #[test]
    fn did_you_mean_suggests_close_names_only() {
        let names = ["roughness_deg", "thickness", "absorption"];
        assert_eq!(did_you_mean("rougness_deg", names), Some("roughness_deg"));
        assert_eq!(did_you_mean("colour", names), None);
        // A short name takes one edit, not two.
        assert_eq!(did_you_mean("Jbo", ["Job", "Gem"]), Some("Job"));
        assert_eq!(did_you_mean("Foo", ["Job", "Gem"]), None);
    }
}
