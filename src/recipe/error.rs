//! Errors in recipes and material files, always with the file and, where
//! known, the line and column: `file:line:col: message`.

use std::fmt;

/// A problem with a user's (or a built-in) RON file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RecipeError {
    /// The file (or `builtin:NAME` for embedded files).
    pub path: String,
    /// 1-based line and column, when the problem has a place in the text.
    pub position: Option<(usize, usize)>,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl RecipeError {
    /// An error with a position in the file.
    pub fn at(path: &str, line: usize, col: usize, message: impl Into<String>) -> Self {
        RecipeError {
            path: path.to_string(),
            position: Some((line, col)),
            message: message.into(),
        }
    }

    /// An error about the whole file (unreadable, missing).
    pub fn whole_file(path: &str, message: impl Into<String>) -> Self {
        RecipeError {
            path: path.to_string(),
            position: None,
            message: message.into(),
        }
    }

    /// An error at the first occurrence of `needle` in `source` (or the
    /// whole file if it does not occur), for problems found after parsing.
    pub fn at_text(path: &str, source: &str, needle: &str, message: impl Into<String>) -> Self {
        match find_position(source, needle, 0) {
            Some((line, col)) => RecipeError::at(path, line, col, message),
            None => RecipeError::whole_file(path, message),
        }
    }
}

impl fmt::Display for RecipeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.position {
            Some((line, col)) => write!(f, "{}:{}:{}: {}", self.path, line, col, self.message),
            None => write!(f, "{}: {}", self.path, self.message),
        }
    }
}

impl std::error::Error for RecipeError {}

/// 1-based line and column of the `nth` (0-based) occurrence of `needle`.
pub fn find_position(source: &str, needle: &str, nth: usize) -> Option<(usize, usize)> {
    let offset = source.match_indices(needle).nth(nth)?.0;
    Some(line_col_of_offset(source, offset))
}

/// 1-based line and column of a byte offset.
pub fn line_col_of_offset(source: &str, offset: usize) -> (usize, usize) {
    let before = &source[..offset.min(source.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// The name of the field whose value starts at or before (line, col): the
/// last `identifier:` in the text up to that point. RON's type errors
/// ("Expected float") do not name the field; this recovers it.
pub fn field_before(source: &str, line: usize, col: usize) -> Option<String> {
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

/// The closest of `candidates` to `word` by edit distance, if close enough
/// to be a likely typo.
pub fn did_you_mean<'a>(
    word: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (strsim::damerau_levenshtein(word, c), c))
        .filter(|(d, c)| *d <= 2.max(c.len() / 3))
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
    fn did_you_mean_suggests_close_names_only() {
        let names = ["roughness_deg", "thickness", "absorption"];
        assert_eq!(did_you_mean("rougness_deg", names), Some("roughness_deg"));
        assert_eq!(did_you_mean("colour", names), None);
    }
}
