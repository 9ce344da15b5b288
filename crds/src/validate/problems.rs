//! The problem list `validate` fills: one [`FieldError`] per problem, and helpers that
//! phrase range, duration and name checks the same way everywhere.

use std::fmt;

use kube::core::Duration;

/// One problem: where and what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldError {
    /// Path from the document root, e.g. `spec.fleet[2].count`.
    pub path: String,
    /// What is wrong and what is expected.
    pub message: String,
}

impl fmt::Display for FieldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.message)
    }
}

impl FieldError {
    /// A problem whose path or message quotes the user's text (a key, a tag, a value as
    /// serde shows it), with control characters escaped (`\n` as the two characters `\`
    /// and `n`): every problem is one line where it is printed, one per line.
    pub(crate) fn quoting(path: &str, message: &str) -> Self {
        Self { path: escape_controls(path), message: escape_controls(message) }
    }
}

/// `text` with its control characters escaped as Rust writes them (`\n`, `\u{1b}`), the
/// rest as it is (non-ASCII letters too).
fn escape_controls(text: &str) -> String {
    if !text.chars().any(char::is_control) {
        return text.to_string();
    }
    text.chars().map(|c| if c.is_control() { c.escape_debug().to_string() } else { c.to_string() }).collect()
}

/// Every problem found in one run, in document order.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct ValidationErrors(pub Vec<FieldError>);

impl fmt::Display for ValidationErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

/// Collects problems with helpers that phrase range checks the same way everywhere.
#[derive(Default)]
pub(super) struct Problems(pub(super) Vec<FieldError>);

impl Problems {
    pub(super) fn add(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.0.push(FieldError { path: path.into(), message: message.into() });
    }

    /// `lo <= value <= hi` and finite. Returns whether the value passed.
    pub(super) fn range(&mut self, path: impl Into<String>, value: f64, lo: f64, hi: f64) -> bool {
        if !value.is_finite() {
            self.add(path, format!("must be a finite number between {lo} and {hi}, got {value}"));
            false
        } else if value < lo || value > hi {
            self.add(path, format!("must be between {lo} and {hi}, got {value}"));
            false
        } else {
            true
        }
    }

    pub(super) fn range_int(&mut self, path: impl Into<String>, value: u64, lo: u64, hi: u64) -> bool {
        if value < lo || value > hi {
            self.add(path, format!("must be between {lo} and {hi}, got {value}"));
            false
        } else {
            true
        }
    }

    /// At most `max` list entries (the CRD's `maxItems`, so a file that passes here also
    /// passes `kubectl apply`).
    pub(super) fn max_items(&mut self, path: impl Into<String>, len: usize, max: usize) {
        if len > max {
            self.add(path, format!("must have at most {max} entries, got {len}"));
        }
    }

    /// A positive duration no longer than `max_s`.
    pub(super) fn duration(&mut self, path: impl Into<String>, d: &Duration, max_s: f64) -> Option<f64> {
        let s = duration_s(d);
        if s <= 0.0 {
            self.add(path, format!("must be a positive duration such as `90s` or `15m`, got {d}"));
            None
        } else if s > max_s {
            self.add(path, format!("must be at most {max_s} s, got {d}"));
            None
        } else {
            Some(s)
        }
    }

    /// RFC 1123 label: lowercase alphanumerics and '-', starting and ending alphanumeric.
    pub(super) fn dns_label(&mut self, path: impl Into<String>, value: &str, max_len: usize) {
        if !is_dns_label(value, max_len) {
            self.add(
                path,
                format!(
                    "must be a DNS label of at most {max_len} characters (lowercase letters, digits, '-'), got {value:?}"
                ),
            );
        }
    }
}

/// Whether `value` is a DNS label (RFC 1123: lowercase letters, digits and inner '-') of at
/// most `max_len` characters.
pub(crate) fn is_dns_label(value: &str, max_len: usize) -> bool {
    !value.is_empty()
        && value.len() <= max_len
        && value.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'-')
        && !value.starts_with('-')
        && !value.ends_with('-')
}

/// Simulated seconds of a (possibly negative) Go duration.
pub fn duration_s(d: &Duration) -> f64 {
    let s = std::time::Duration::from(*d).as_secs_f64();
    if d.is_negative() { -s } else { s }
}
