//! One error type for every bad-input case: it names the file, the field and, where known, the
//! line, so a user can fix a preset without reading code.

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    pub file: String,
    pub field: String,
    pub line: Option<usize>,
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": field `{}`", self.field)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SceneError {}

/// Builds errors for one preset file and finds the line where a field is set.
#[derive(Debug, Clone)]
pub struct ErrorContext<'a> {
    pub file: &'a str,
    pub text: &'a str,
    pub variant: Option<&'a str>,
}

impl ErrorContext<'_> {
    pub fn error(&self, field: &str, message: impl Into<String>) -> SceneError {
        let mut message = message.into();
        if let Some(v) = self.variant {
            message = format!("{message} (variant `{v}`)");
        }
        SceneError {
            file: self.file.to_string(),
            field: field.to_string(),
            line: locate_field(self.text, field),
            message,
        }
    }

    /// Converts a `field: message` string from a nested validator.
    pub fn from_path_message(&self, path_message: &str) -> SceneError {
        match path_message.split_once(": ") {
            Some((field, msg)) if !field.contains(' ') => self.error(field, msg),
            _ => self.error("", path_message),
        }
    }
}

/// Line (1-based) of a byte offset.
pub fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// Best-effort line of `a.b[2].key`: the first `key =` after the header of table `a`.
pub fn locate_field(text: &str, field: &str) -> Option<usize> {
    let segments: Vec<&str> = field
        .split('.')
        .map(|s| s.split('[').next().unwrap_or(s))
        .filter(|s| !s.is_empty())
        .collect();
    let key = *segments.last()?;
    let table = segments.first().copied().filter(|_| segments.len() > 1);
    let mut in_table = table.is_none();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        if t.starts_with('[') {
            let header = t.trim_start_matches('[').trim_end_matches(']');
            if let Some(table) = table {
                in_table = header == table || header.starts_with(&format!("{table}."));
            }
            continue;
        }
        if !in_table {
            continue;
        }
        let is_key = |s: &str| {
            s.strip_prefix(key)
                .map(|rest| rest.trim_start().starts_with('='))
                .unwrap_or(false)
        };
        if is_key(t) || t.split(['{', ',']).any(|part| is_key(part.trim_start())) {
            return Some(i + 1);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_keys_in_tables_and_inline_tables() {
        let text = "name = \"x\"\n[discretization]\nspacing = 1\nhorizon_factor = -4\n[time]\ndt = { a = 1, spacing = 3 }\n";
        assert_eq!(locate_field(text, "discretization.horizon_factor"), Some(4));
        assert_eq!(locate_field(text, "discretization.spacing"), Some(3));
        assert_eq!(locate_field(text, "name"), Some(1));
        assert_eq!(locate_field(text, "time.spacing"), Some(6));
    }
}
