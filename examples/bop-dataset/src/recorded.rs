//! Settings recorded beside the files they produced (`synth_options.json`,
//! `label_options.json`), so that a rerun with other settings is refused rather than completed
//! into a mixture.
use std::path::Path;

use serde_json::Value;

use crate::{FileError, read_json};

/// `value` as it reads back from a file: numbers pass through JSON text once, so that a
/// recorded `0.1` compares equal to the `0.1` computed now.
pub fn as_recorded(value: Value) -> Value {
    serde_json::from_str(&value.to_string()).unwrap_or(value)
}

/// Refuses the settings recorded at `path` when they differ from `expected` (an object), naming
/// the first key that differs, what was recorded and what this run asks for; `remedy` says
/// what to do instead. A key on one side only stands for `null` on the other (settings recorded
/// only where used: a split made with one is refused to a run without it, and the reverse). A
/// missing file (nothing recorded yet, or an older version) is accepted.
pub fn check_recorded(path: &Path, expected: &Value, remedy: &str) -> Result<(), FileError> {
    if !path.exists() {
        return Ok(());
    }
    let recorded = read_json(path)?;
    let Some(recorded) = recorded.as_object() else {
        return Err(FileError::new(path, "file", "not a JSON object"));
    };
    let Some(expected) = expected.as_object() else {
        return Ok(());
    };
    let recorded_only = recorded.keys().filter(|key| !expected.contains_key(*key));
    for key in expected.keys().chain(recorded_only) {
        let found = recorded.get(key).unwrap_or(&Value::Null);
        let value = expected.get(key).unwrap_or(&Value::Null);
        if found != value {
            return Err(FileError::new(
                path,
                key,
                format!("recorded {found}, this run asks for {value}; {remedy}"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    #[test]
    fn the_first_differing_setting_is_named_with_both_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("options.json");
        let settings = as_recorded(json!({"seed": 1, "scale": 0.1}));
        check_recorded(&path, &settings, "fix it").unwrap();
        crate::write_json(&path, &settings).unwrap();
        check_recorded(&path, &settings, "fix it").unwrap();
        let other = as_recorded(json!({"seed": 1, "scale": 0.2}));
        let error = check_recorded(&path, &other, "fix it")
            .unwrap_err()
            .to_string();
        assert!(error.contains("scale") && error.contains("0.1") && error.contains("0.2"));
        assert!(error.ends_with("fix it"), "{error}");
        // A setting recorded only where used: the split made with it is refused to a run
        // without it.
        let with = as_recorded(json!({"seed": 1, "scale": 0.1, "occluders": 2}));
        crate::write_json(&path, &with).unwrap();
        let error = check_recorded(&path, &settings, "fix it")
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("occluders") && error.contains("null"),
            "{error}"
        );
    }
}
