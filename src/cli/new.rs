//! `lapidary new NAME --from TEMPLATE [-o PATH]`: start a recipe from a
//! built-in gem or material. The template's own text (with its comments)
//! is copied under a header saying where it came from and how to check and
//! render it; a gem's `name:` becomes NAME, its `description:` says where it
//! started. The result is validated before it is written, atomically, and
//! an existing file is never overwritten.

use super::validate::validate_text;
use lapidary::recipe::error::{did_you_mean, line_col_of_offset};
use lapidary::recipe::library::{
    builtin_gem_names, builtin_gem_source, builtin_material_names, builtin_material_source,
};
use std::path::{Path, PathBuf};

/// Arguments of `lapidary new`.
#[derive(clap::Args, Debug)]
pub struct NewArgs {
    /// Name of the new recipe (letters, digits, `-`, `_`, not starting with
    /// `-`); the file is NAME.ron.
    name: String,
    /// The built-in gem or material to start from (see `lapidary list`).
    #[arg(long = "from", value_name = "TEMPLATE")]
    from: String,
    /// Where to write (default: NAME.ron in the current folder).
    #[arg(short = 'o', long = "output", value_name = "PATH")]
    output: Option<PathBuf>,
}

/// A template's kind and RON text.
enum Template {
    Gem(&'static str),
    Material(&'static str),
}

/// Find TEMPLATE among the built-in gems and materials; an unknown name
/// gets a did-you-mean and the list of templates.
fn template(name: &str) -> Result<Template, String> {
    if let Some(text) = builtin_gem_source(name) {
        return Ok(Template::Gem(text));
    }
    if let Some(text) = builtin_material_source(name) {
        return Ok(Template::Material(text));
    }
    let all: Vec<&str> = builtin_gem_names()
        .chain(builtin_material_names())
        .collect();
    let hint = did_you_mean(name, all.iter().copied())
        .map(|s| format!(" (did you mean `{s}`?)"))
        .unwrap_or_default();
    Err(format!(
        "--from {name}: no built-in template of that name{hint}; gems: {}; materials: {}",
        builtin_gem_names().collect::<Vec<_>>().join(", "),
        builtin_material_names().collect::<Vec<_>>().join(", ")
    ))
}

/// NAME must be usable both as a file name and inside a RON string, and
/// as a command's argument (not starting with `-`, an option's mark).
fn check_name(name: &str) -> Result<(), String> {
    if name.starts_with('-') {
        return Err(format!(
            "NAME `{name}`: must not start with `-` (commands would read the file as an option)"
        ));
    }
    let ok = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || c == '-' || c == '_');
    if ok {
        Ok(())
    } else {
        Err(format!(
            "NAME `{name}`: allowed a non-empty name of letters, digits, `-` and `_`"
        ))
    }
}

/// Byte range of the string value of the top-level field `field` (`name`,
/// `description`) of the `Gem(` in `text` (quotes included), skipping
/// comments and strings and looking only at nesting depth 1; `None` when
/// the gem has no such field.
fn gem_field_value(text: &str, field: &str) -> Option<(usize, usize)> {
    let b = text.as_bytes();
    let mut depth = 0usize;
    let mut i = 0;
    let is_word = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    while i < b.len() {
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                i += text[i..].find('\n').unwrap_or(text.len() - i);
                continue;
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                i += text[i + 2..].find("*/").map_or(text.len() - i, |e| e + 4);
                continue;
            }
            b'"' => {
                i += 1;
                while i < b.len() && b[i] != b'"' {
                    i += if b[i] == b'\\' { 2 } else { 1 };
                }
            }
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => depth = depth.saturating_sub(1),
            c if c == field.as_bytes()[0]
                && depth == 1
                && text[i..].starts_with(field)
                && (i == 0 || !is_word(b[i - 1]))
                && !b.get(i + field.len()).is_some_and(|c| is_word(*c)) =>
            {
                let after = text[i + field.len()..].trim_start();
                if let Some(value) = after.strip_prefix(':') {
                    let value = value.trim_start();
                    if value.starts_with('"') {
                        let start = text.len() - value.len();
                        let mut k = start + 1;
                        while k < b.len() && b[k] != b'"' {
                            k += if b[k] == b'\\' { 2 } else { 1 };
                        }
                        return Some((start, (k + 1).min(b.len())));
                    }
                }
            }
            _ => {}
        }
        i += 1;
    }
    None
}

/// The template's text with the gem's `name:` set to NAME (inserted after
/// `Gem(` when the template has none) and its `description:`, if any,
/// saying it was started from `template` (lists and the gallery show it).
fn rename_gem(text: &str, name: &str, template: &str) -> String {
    let text = match gem_field_value(text, "description") {
        Some((start, end)) => format!(
            "{}\"{name}, started from {template}: {}\"{}",
            &text[..start],
            &text[start + 1..end - 1],
            &text[end..]
        ),
        None => text.to_string(),
    };
    let text = text.as_str();
    match gem_field_value(text, "name") {
        Some((start, end)) => format!("{}\"{name}\"{}", &text[..start], &text[end..]),
        None => match text.find("Gem(") {
            Some(at) => {
                let open = at + "Gem(".len();
                format!("{}\n    name: \"{name}\",{}", &text[..open], &text[open..])
            }
            None => text.to_string(),
        },
    }
}

/// The header comment of a new recipe: its origin and the next commands.
fn header(name: &str, template: &str, kind: &str, path: &Path, is_gem: bool) -> String {
    let file = path.display();
    let mut commands = vec![(
        format!("lapidary validate {file}"),
        "check every field and name",
    )];
    if is_gem {
        commands.push((
            format!("lapidary render {file} -o {name}.png"),
            "render it on a cabochon",
        ));
    } else {
        commands.push((
            format!("lapidary brdf {file} -o {name}.png"),
            "polar plots of its BRDF",
        ));
        commands.push((format!("lapidary classify {file}"), "its section 3.4 class"));
    }
    let width = commands.iter().map(|(c, _)| c.len()).max().unwrap_or(0);
    let lines: String = commands
        .iter()
        .map(|(command, why)| format!("//   {command:<width$}  # {why}\n"))
        .collect();
    format!(
        "// {name}: a {kind} started from the built-in {kind} `{template}`\n\
         // (`lapidary new {name} --from {template}`). Edit it, then:\n\
         {lines}\
         // Every field, its unit, default and range: docs/recipes.md.\n\
         // The template's own notes follow.\n\n"
    )
}

/// Run `lapidary new`.
pub fn run(args: NewArgs) -> Result<(), String> {
    let name = args
        .name
        .strip_suffix(".ron")
        .unwrap_or(&args.name)
        .to_string();
    check_name(&name)?;
    let template = template(&args.from)?;
    let path = args
        .output
        .unwrap_or_else(|| PathBuf::from(format!("{name}.ron")));
    if path.as_os_str() == "-" {
        return Err(
            "-o -: `lapidary new` writes a file; give its path (e.g. -o my-gem.ron)".into(),
        );
    }
    if path.extension().is_none_or(|e| e != "ron") {
        return Err(format!(
            "{}: `lapidary new` writes RON text; allowed: a path ending in .ron",
            path.display()
        ));
    }
    if path.symlink_metadata().is_ok() {
        return Err(format!(
            "{}: already exists; not overwriting it (choose another NAME or -o PATH)",
            path.display()
        ));
    }
    lapidary::output::check_writable(&path).map_err(|e| e.to_string())?;
    let (body, kind, is_gem) = match template {
        Template::Gem(text) => (rename_gem(text, &name, &args.from), "gem recipe", true),
        Template::Material(text) => (text.to_string(), "material", false),
    };
    let text = format!("{}{body}", header(&name, &args.from, kind, &path, is_gem));
    // What is written must validate: check the text before writing it.
    let checked = validate_text(&path.display().to_string(), None, &name, &text);
    if let Err(e) = checked {
        return Err(format!(
            "the recipe made from `{}` does not validate (a bug in lapidary): {e}",
            args.from
        ));
    }
    lapidary::output::write_atomically(&path, text.as_bytes()).map_err(|e| e.to_string())?;
    let (line, _) = gem_field_value(&text, "name")
        .filter(|_| is_gem)
        .map_or((1, 1), |(start, _)| line_col_of_offset(&text, start));
    eprintln!(
        "wrote {} ({kind} from `{}`{}); next: lapidary validate {}",
        path.display(),
        args.from,
        if is_gem {
            format!(", name on line {line}")
        } else {
            String::new()
        },
        path.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_gems_own_name_field_is_replaced() {
        // A `name:` in a comment, in a string and inside a nested struct
        // must stay; the depth-1 field changes.
        let text = "// name: \"c\"\nGem(\n  description: \"name: x\",\n  maps: {\"m\": S(name: \"inner\")},\n  name: \"old\",\n)";
        let out = rename_gem(text, "new-one", "t");
        assert!(out.contains("name: \"new-one\""), "{out}");
        assert!(!out.contains("\"old\""), "{out}");
        for kept in ["// name: \"c\"", "name: \"inner\""] {
            assert!(out.contains(kept), "{kept} lost: {out}");
        }
        // The description says where the gem came from, and keeps its own.
        assert!(
            out.contains("description: \"new-one, started from t: name: x\""),
            "{out}"
        );
    }

    #[test]
    fn a_gem_without_a_name_gets_one() {
        let out = rename_gem("Gem(surface: \"gold\")", "g", "t");
        assert_eq!(
            gem_field_value(&out, "name").map(|(s, e)| &out[s..e]),
            Some("\"g\"")
        );
    }

    #[test]
    fn names_that_cannot_be_files_or_strings_are_refused() {
        assert!(check_name("my-gem_2").is_ok());
        for bad in ["", "a b", "x/y", "q\"", "../up"] {
            assert!(check_name(bad).is_err(), "{bad:?} accepted");
        }
    }
}
