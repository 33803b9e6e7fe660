//! Command-line variations of a scenario: `run --set PATH=VALUE` replaces (or adds) the field
//! at a JSON path of the scenario, `run --sweep AXIS=V1,V2,...` sets the sweep axis `AXIS`.
//! They are applied to the scenario's JSON before it is read, so the result is validated as
//! the file is; an error in an overridden field names the flag and its path.

use serde_json::Value;

use crate::error::InputError;

/// One override: the scenario field at `path` (dot-separated keys, `[i]` for an element of a
/// list: `options.pcss.pcf_samples`, `scene.objects[0].scale`) set to `value`.
#[derive(Clone, Debug, PartialEq)]
pub struct Override {
    /// `--set` or `--sweep`, for errors.
    pub flag: &'static str,
    /// The JSON path without the leading `$.`.
    pub path: String,
    pub value: Value,
}

/// A value as the user typed it: JSON where it parses (`16`, `true`, `[160,120]`, `"x"`), else
/// the text as a string (`sphere-on-plane`).
fn value_of(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|_| Value::String(text.to_string()))
}

fn split<'a>(flag: &str, arg: &'a str, example: &str) -> Result<(&'a str, &'a str), InputError> {
    match arg.split_once('=') {
        Some((p, v)) if !p.trim().is_empty() && !v.is_empty() => Ok((p.trim(), v)),
        _ => Err(InputError::new(
            flag,
            format!("expected PATH=VALUE (e.g. {example}), got '{arg}'"),
        )),
    }
}

impl Override {
    /// `--set PATH=VALUE`.
    pub fn set(arg: &str) -> Result<Override, InputError> {
        let (path, value) = split("--set", arg, "options.pcss.pcf_samples=16")?;
        segments("--set", path)?;
        Ok(Override {
            flag: "--set",
            path: path.to_string(),
            value: value_of(value),
        })
    }

    /// `--sweep AXIS=V1,V2,...`: the list `[V1, V2, ...]` for `sweep.AXIS` (values JSON, so
    /// `image=[160,120],[320,240]` gives two sizes; text that is not JSON splits at commas).
    pub fn sweep(arg: &str) -> Result<Override, InputError> {
        let (axis, values) = split("--sweep", arg, "light_size=0.3,0.6")?;
        if axis.contains(['.', '[']) {
            return Err(InputError::new(
                "--sweep",
                format!("'{axis}' is not a sweep axis name (e.g. light_size)"),
            ));
        }
        let value = serde_json::from_str::<Value>(&format!("[{values}]"))
            .unwrap_or_else(|_| Value::Array(values.split(',').map(value_of).collect()));
        Ok(Override {
            flag: "--sweep",
            path: format!("sweep.{axis}"),
            value,
        })
    }

    /// How the record names it: `options.pcss.pcf_samples=16`.
    pub fn describe(&self) -> String {
        format!("{}={}", self.path, self.value)
    }

    /// The field errors name: `$.options.pcss.pcf_samples`.
    fn json_path(&self) -> String {
        format!("$.{}", self.path)
    }

    /// Sets the field in `doc`, making the objects on the way that are missing.
    pub fn apply(&self, doc: &mut Value) -> Result<(), InputError> {
        let segs = segments(self.flag, &self.path)?;
        let mut at = doc;
        for (i, seg) in segs.iter().enumerate() {
            let last = i + 1 == segs.len();
            at = match seg {
                Segment::Key(k) => {
                    if at.is_null() {
                        *at = Value::Object(Default::default());
                    }
                    let Value::Object(map) = at else {
                        return Err(self.error(&segs[..i], "is not an object"));
                    };
                    if last {
                        map.insert(k.clone(), self.value.clone());
                        return Ok(());
                    }
                    map.entry(k.clone()).or_insert(Value::Null)
                }
                Segment::Index(n) => {
                    let Value::Array(list) = at else {
                        return Err(self.error(&segs[..i], "is not a list"));
                    };
                    let len = list.len();
                    let Some(item) = list.get_mut(*n) else {
                        return Err(self
                            .error(&segs[..i], &format!("has {len} elements, no element [{n}]")));
                    };
                    if last {
                        *item = self.value.clone();
                        return Ok(());
                    }
                    item
                }
            };
        }
        Ok(())
    }

    fn error(&self, upto: &[Segment], what: &str) -> InputError {
        let mut p = "$".to_string();
        for s in upto {
            match s {
                Segment::Key(k) => p += &format!(".{k}"),
                Segment::Index(n) => p += &format!("[{n}]"),
            }
        }
        InputError::new(
            format!("{} {}", self.flag, self.path),
            format!("cannot set it: {p} {what}"),
        )
    }

    /// Whether an error at JSON path `field` lies in this override's field (or contains it).
    fn covers(&self, field: &str) -> bool {
        let own = self.json_path();
        let within = |a: &str, b: &str| {
            a.strip_prefix(b)
                .is_some_and(|rest| rest.is_empty() || rest.starts_with(['.', '[']))
        };
        within(field, &own) || within(&own, field)
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Segment {
    Key(String),
    Index(usize),
}

/// `a.b[2].c` → `a`, `b`, `[2]`, `c`; an empty key or a bad index is an error naming `flag`.
fn segments(flag: &str, path: &str) -> Result<Vec<Segment>, InputError> {
    let bad = |why: &str| InputError::new(flag, format!("bad JSON path '{path}': {why}"));
    let path = path.strip_prefix("$.").unwrap_or(path);
    let mut out = Vec::new();
    for part in path.split('.') {
        let (key, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        if key.is_empty() {
            return Err(bad("an empty field name"));
        }
        out.push(Segment::Key(key.to_string()));
        while !rest.is_empty() {
            let close = rest.find(']').ok_or_else(|| bad("a '[' without ']'"))?;
            let n = rest[1..close]
                .parse::<usize>()
                .map_err(|_| bad("an index that is not a number"))?;
            out.push(Segment::Index(n));
            rest = &rest[close + 1..];
            if !rest.is_empty() && !rest.starts_with('[') {
                return Err(bad("text after ']'"));
            }
        }
    }
    Ok(out)
}

/// Applies `overrides` in order to the scenario JSON `doc`.
pub fn apply_all(doc: &mut Value, overrides: &[Override]) -> Result<(), InputError> {
    if !doc.is_object() {
        return Err(InputError::new("$", "a scenario is a JSON object"));
    }
    overrides.iter().try_for_each(|o| o.apply(doc))
}

/// An error of the scenario read with `overrides` applied: one in an overridden field names the
/// flag and the field (`--set options.pcss.pcf_samples ($.options.pcss.pcf_samples)`).
pub fn attribute(mut e: InputError, overrides: &[Override]) -> InputError {
    let Some(field) = e.field.clone() else {
        return e;
    };
    if let Some(o) = overrides.iter().rev().find(|o| o.covers(&field)) {
        e.field = Some(format!("{} {}={} ({field})", o.flag, o.path, o.value));
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn set_replaces_or_adds_a_field_by_its_path() {
        let mut doc = json!({"options": {"pcss": {"pcf_samples": 32}}, "scene": {"objects": [{"obj": "a.obj"}]}});
        Override::set("options.pcss.pcf_samples=16")
            .unwrap()
            .apply(&mut doc)
            .unwrap();
        Override::set("options.penumbra_map.bias=0.5")
            .unwrap()
            .apply(&mut doc)
            .unwrap();
        Override::set("scene.objects[0].scale=2")
            .unwrap()
            .apply(&mut doc)
            .unwrap();
        Override::set("scene.generator=torus-on-plane")
            .unwrap()
            .apply(&mut doc)
            .unwrap();
        assert_eq!(doc["options"]["pcss"]["pcf_samples"], 16);
        assert_eq!(doc["options"]["penumbra_map"]["bias"], 0.5);
        assert_eq!(doc["scene"]["objects"][0]["scale"], 2);
        assert_eq!(doc["scene"]["generator"], "torus-on-plane");
        let e = Override::set("scene.objects[3].scale=2")
            .unwrap()
            .apply(&mut doc)
            .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("--set scene.objects[3].scale"));
        assert!(e.message.contains("has 1 elements"), "{}", e.message);
        assert!(Override::set("options.pcss").is_err());
        assert!(Override::set("a..b=1").is_err());
    }

    #[test]
    fn sweep_makes_a_list_for_the_axis() {
        let o = Override::sweep("light_size=0.3,0.6").unwrap();
        assert_eq!(
            (o.path.as_str(), &o.value),
            ("sweep.light_size", &json!([0.3, 0.6]))
        );
        let o = Override::sweep("image=[160,120],[320,240]").unwrap();
        assert_eq!(o.value, json!([[160, 120], [320, 240]]));
        assert!(Override::sweep("sweep.light_size=1").is_err());
    }

    #[test]
    fn an_error_in_an_overridden_field_names_the_flag() {
        let o = [Override::set("options.pcss.pcf_samples=0").unwrap()];
        let e = attribute(
            InputError::new("$.options.pcss.pcf_samples", "must be in 1..=64"),
            &o,
        );
        assert_eq!(
            e.field.as_deref(),
            Some("--set options.pcss.pcf_samples=0 ($.options.pcss.pcf_samples)")
        );
        let e = attribute(InputError::new("$.options.pcss", "unknown field"), &o);
        assert!(e.field.unwrap().starts_with("--set"));
        let e = attribute(InputError::new("$.options.pcss_x", "unknown"), &o);
        assert_eq!(e.field.as_deref(), Some("$.options.pcss_x"));
    }
}
