//! Reading one JSON value of a user's file (a scenario, a machine configuration) into a typed
//! value, with errors that name the file, the JSON path and what is wrong: malformed JSON
//! (with its line and column), content after the value (`{…}garbage`, two values pasted into
//! one file), an array with more elements than its field takes (`"image": [1, 2, 3]`), or a
//! field of the wrong type or value (serde's message at its path).

use std::path::Path;

use serde::de::DeserializeOwned;

use crate::error::InputError;

/// Parses `text`, the whole content of `path`, as one `T`. Errors: see the module docs.
pub fn parse<T: DeserializeOwned>(text: &str, path: &Path) -> Result<T, InputError> {
    let de = &mut serde_json::Deserializer::from_str(text);
    let value: T = serde_path_to_error::deserialize(&mut *de).map_err(|e| {
        let field = match e.path().to_string() {
            f if f == "." => "$".to_string(),
            f => format!("$.{f}"),
        };
        let inner = e.into_inner();
        if let Some((takes, got)) = overlong_array(text, &inner) {
            return InputError {
                file: Some(path.to_path_buf()),
                field: Some(field),
                message: format!("takes {takes} values, got {got}"),
            };
        }
        // A number beyond its field's type (`1e39` for an `f32`) is reported by serde_json as
        // a syntax error, but it is the value at its path that is wrong.
        let out_of_range = inner.to_string().starts_with("number out of range");
        let malformed = (inner.is_syntax() && !out_of_range) || inner.is_eof();
        InputError {
            file: Some(path.to_path_buf()),
            field: (!malformed).then_some(field),
            message: if malformed {
                format!("malformed JSON: {inner}")
            } else {
                inner.to_string()
            },
        }
    })?;
    de.end().map_err(|e| {
        InputError::file(
            path,
            format!(
                "content after the JSON value at line {} column {}: a file holds one JSON value",
                e.line(),
                e.column()
            ),
        )
    })?;
    Ok(value)
}

/// serde_json reports a fixed-length array (`[u32; 2]`, a `Vec3`) given more elements as
/// "trailing characters" at the first element after those it took: (elements taken,
/// elements given) of that array, or `None` for any other error.
fn overlong_array(text: &str, e: &serde_json::Error) -> Option<(usize, usize)> {
    if !e.is_syntax() || !e.to_string().starts_with("trailing characters") {
        return None;
    }
    // serde_json's line is 1-based and its column the 1-based byte column of that line.
    let line_start: usize = text
        .split_inclusive('\n')
        .take(e.line().checked_sub(1)?)
        .map(str::len)
        .sum();
    // It points at the first element too many: the comma before it is the array's.
    let first_extra = line_start + e.column().checked_sub(1)?;
    let at = text.as_bytes()[..first_extra.min(text.len())]
        .iter()
        .rposition(|b| !b.is_ascii_whitespace())?;
    if text.as_bytes()[at] != b',' {
        return None;
    }
    // The commas of each open array (`None` for an object), scanning the text in order.
    let mut open: Vec<Option<usize>> = Vec::new();
    let (mut in_string, mut escaped) = (false, false);
    // (depth, elements before the reported comma) of its array, once reached.
    let mut reported: Option<(usize, usize)> = None;
    for (i, &c) in text.as_bytes().iter().enumerate() {
        if in_string {
            match c {
                _ if escaped => escaped = false,
                b'\\' => escaped = true,
                b'"' => in_string = false,
                _ => {}
            }
            continue;
        }
        match c {
            b'"' => in_string = true,
            b'[' => open.push(Some(0)),
            b'{' => open.push(None),
            b']' | b'}' => {
                let depth = open.len();
                let closed = open.pop()?;
                if let (Some((d, taken)), Some(commas)) = (reported, closed) {
                    if d == depth {
                        return Some((taken, commas + 1));
                    }
                }
            }
            b',' => {
                if i == at {
                    let commas = (*open.last()?)?;
                    reported = Some((open.len(), commas + 1));
                }
                if let Some(Some(n)) = open.last_mut() {
                    *n += 1;
                }
            }
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Params {
        image: [u32; 2],
        eye: Option<glam::Vec3>,
        names: Option<Vec<String>>,
    }

    fn err(text: &str) -> InputError {
        parse::<Params>(text, Path::new("s.json")).unwrap_err()
    }

    #[test]
    fn an_array_longer_than_its_field_names_the_field_and_both_counts() {
        let e = err(r#"{"names": ["a,]", "b"], "image": [32, 24, 7]}"#);
        assert_eq!(e.field.as_deref(), Some("$.image"));
        assert_eq!(e.message, "takes 2 values, got 3");
        let e = err("{\n  \"image\": [1, 2],\n  \"eye\": [0, 1, 2, [3], 4]\n}");
        assert_eq!(e.field.as_deref(), Some("$.eye"));
        assert_eq!(e.message, "takes 3 values, got 5");
        assert_eq!(e.file.as_deref(), Some(Path::new("s.json")));
    }

    #[test]
    fn content_after_the_value_is_refused_with_where_it_starts() {
        for text in [
            r#"{"image": [1, 2]}garbage"#,
            "{\"image\": [1, 2]}\n{\"image\": [3, 4]}\n",
        ] {
            let e = err(text);
            assert_eq!(e.file.as_deref(), Some(Path::new("s.json")), "{text}");
            assert!(
                e.message
                    .starts_with("content after the JSON value at line "),
                "{e}"
            );
        }
        assert!(parse::<Params>("{\"image\": [1, 2]}\n\n ", Path::new("s.json")).is_ok());
    }

    #[test]
    fn malformed_json_has_no_field_and_a_wrong_type_has_its_path() {
        let e = err(r#"{"image": [1, 2"#);
        assert_eq!(e.field, None);
        assert!(e.message.starts_with("malformed JSON: EOF"), "{e}");
        let e = err(r#"{"image": "32x24"}"#);
        assert_eq!(e.field.as_deref(), Some("$.image"));
        let e = err(r#"{"image": [1]}"#);
        assert_eq!(e.field.as_deref(), Some("$.image"));
        assert!(e.message.contains("invalid length 1"), "{e}");
    }
}
