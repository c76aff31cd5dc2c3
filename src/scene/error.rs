//! Errors that point at the input: file, line, column and field.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// A problem in a scene or profile file. Displays as `file:line:col: field: message`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InputError {
    pub file: PathBuf,
    pub line: usize,
    pub column: usize,
    /// Dotted path of the offending field (`shapes[2].radius`), or empty for syntax errors.
    pub field: String,
    pub message: String,
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}: ", self.file.display(), self.line, self.column)?;
        if !self.field.is_empty() {
            write!(f, "field `{}`: ", self.field)?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for InputError {}

/// The source text of one input file, for turning byte spans into line and column.
pub struct Source<'a> {
    pub path: &'a Path,
    pub text: &'a str,
}

impl Source<'_> {
    /// 1-based line and column of a byte offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.text.len());
        let before = &self.text.as_bytes()[..offset];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let line_start = before.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let column = String::from_utf8_lossy(&before[line_start..]).chars().count() + 1;
        (line, column)
    }

    pub fn error(&self, span: Range<usize>, field: impl Into<String>, message: impl Into<String>) -> InputError {
        let (line, column) = self.line_col(span.start);
        InputError { file: self.path.to_path_buf(), line, column, field: field.into(), message: message.into() }
    }

    /// Convert a TOML syntax or type error into an `InputError` (the toml crate already names the key).
    pub fn from_toml(&self, e: &toml::de::Error) -> InputError {
        let span = e.span().unwrap_or(0..0);
        let message = e.message().trim().to_string();
        // The toml crate puts the offending key in its message ("unknown field `x`", "missing field `y`").
        let field = extract_backticked(&message).unwrap_or_default();
        self.error(span, field, message)
    }
}

fn extract_backticked(s: &str) -> Option<String> {
    let a = s.find('`')?;
    let b = s[a + 1..].find('`')?;
    Some(s[a + 1..a + 1 + b].to_string())
}

/// Read a file as UTF-8 text, with an `InputError` (line 1) for unreadable or non-UTF-8 files.
pub fn read_text(path: &Path) -> Result<String, InputError> {
    let err = |line: usize, message: String| InputError { file: path.to_path_buf(), line, column: 1, field: String::new(), message };
    let bytes = std::fs::read(path).map_err(|e| err(1, format!("cannot read file: {e}")))?;
    if bytes.len() > MAX_INPUT_BYTES {
        return Err(err(1, format!("file is {} bytes; the limit is {MAX_INPUT_BYTES}", bytes.len())));
    }
    String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        err(line, format!("file is not valid UTF-8 (byte {})", e.utf8_error().valid_up_to()))
    })
}

/// Scene files larger than this are refused before parsing (protects the machine).
pub const MAX_INPUT_BYTES: usize = 16 << 20;
