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
        // Line 0: the input is not a position in a file (a `--profile` name that names nothing).
        if self.line == 0 {
            write!(f, "{}: ", self.file.display())?;
        } else {
            write!(f, "{}:{}:{}: ", self.file.display(), self.line, self.column)?;
        }
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
        // (A byte-order mark opening the file is no column of its line.)
        let bom = usize::from(line_start == 0 && self.text.starts_with('\u{feff}') && offset >= 3);
        let column = String::from_utf8_lossy(&before[line_start..]).chars().count() + 1 - bom;
        (line, column)
    }

    pub fn error(&self, span: Range<usize>, field: impl Into<String>, message: impl Into<String>) -> InputError {
        let (line, column) = self.line_col(span.start);
        InputError { file: self.path.to_path_buf(), line, column, field: field.into(), message: message.into() }
    }

    /// Convert a TOML syntax or type error into an `InputError`. "unknown field `x`" and "missing field
    /// `x`" name the key; the other messages do not ("invalid type: string \"big\", expected f32",
    /// "invalid length 4", "duplicate key"), and their backticked text, if any, is a value: the field is
    /// then the key written at the error's position (the key of the `key = value` on that line).
    pub fn from_toml(&self, e: &toml::de::Error) -> InputError {
        let span = e.span().unwrap_or(0..0);
        let message = e.message().trim().to_string();
        if message.contains("recursion limit") {
            // The reader's own nesting limit (about 80 levels of `[[shapes.children...]]` headers) comes
            // without a position: the deepest header is the place to look.
            let (at, _) = self.text.lines().enumerate().fold((0, 0), |best, (i, l)| {
                let depth = if l.trim_start().starts_with('[') { l.matches('.').count() } else { 0 };
                if depth > best.1 {
                    (i, depth)
                } else {
                    best
                }
            });
            let start = self.text.lines().take(at).map(|l| l.len() + 1).sum::<usize>();
            let msg = "nested deeper than the TOML reader allows (its recursion limit); CSG trees may be at most 64 levels deep";
            return self.error(start..start, self.key_at(start), msg.to_string());
        }
        let line = self.text[span.start.min(self.text.len())..].lines().next().unwrap_or("").trim_start();
        if line.starts_with("[[") && (message.starts_with("invalid type: map") || message.starts_with("invalid length")) {
            // `[[materials.x]]` (an array of tables) where one table belongs: serde read the array as the
            // table's fields in order, and its words ("expected a string", "expected struct MaterialDef
            // with 15 elements") name the wrong thing.
            let msg = "`[[...]]` makes an array of tables; a single table belongs here: write `[...]`".to_string();
            return self.error(span.clone(), self.key_at(span.start), msg);
        }
        if !line.starts_with("[[") && line.starts_with('[') && message.starts_with("invalid type: map, expected a sequence") {
            // `[lights]` where `[[lights]]` belongs (shapes, lights: arrays of tables).
            let name = self.key_at(span.start);
            let msg = format!("`[{name}]` makes one table; `{name}` is a list: write `[[{name}]]` before each entry");
            return self.error(span.clone(), name, msg);
        }
        if message == "duplicate key" {
            // A table header or a key written twice: say which, and for the lists how to write several.
            let name = self.key_at(span.start);
            let at = span.start.min(self.text.len());
            let line_start = self.text[..at].rfind('\n').map_or(0, |i| i + 1);
            // A header whose name was given earlier as a value (`shapes = 3`, then `[[shapes]]`; `transform =
            // {...}`, then `[shapes.transform]`), or as a header: looked for in the table the header belongs
            // to, since the last `[[parent]]` header where the parent is a list (the entry being written:
            // a generated file's other entries are not it), the value directly under the parent's header.
            let (parent, last) = name.rsplit_once('.').unwrap_or(("", &name));
            let before: Vec<&str> = self.text[..line_start].lines().collect();
            let scope = before.iter().rposition(|l| table_header(l).is_some_and(|(list, n)| list && n == parent)).unwrap_or(0);
            let (mut as_value, mut as_header, mut table) = (None, false, None::<String>);
            for (i, l) in before.iter().enumerate().skip(scope) {
                if let Some((_, n)) = table_header(l) {
                    as_header |= n == name;
                    table = Some(n);
                    continue;
                }
                let in_parent = table.as_deref().map_or(parent.is_empty(), |t| t == parent);
                let is_value = l
                    .trim_start()
                    .strip_prefix(last)
                    .is_some_and(|r| r.trim_start().starts_with('=') && !r.starts_with(|c: char| c.is_alphanumeric() || c == '_'));
                if in_parent && is_value {
                    as_value = Some(i);
                }
            }
            let msg = if !self.text[line_start..].trim_start().starts_with('[') {
                format!("`{name}` is given twice in one table")
            } else if let (Some(at), false) = (as_value, as_header) {
                let header =
                    if self.text[line_start..].trim_start().starts_with("[[") { format!("[[{name}]]") } else { format!("[{name}]") };
                format!("`{last}` is already given a value at line {}; it cannot also be a table `{header}`", at + 1)
            } else if name == "shapes" || name == "lights" {
                format!("`[{name}]` appears twice; `{name}` is a list: write `[[{name}]]` before each entry")
            } else {
                format!("table `[{name}]` is defined twice; a table's header may appear once")
            };
            return self.error(span, name, msg);
        }
        let named = message.strip_prefix("unknown field ").or_else(|| message.strip_prefix("missing field "));
        let key = self.key_at(span.start);
        if let (None, Some((path, array, inner))) = (named, self.element_path(span.start)) {
            // A value that is an element of an array where the key on its line (if any) is another's
            // (`children = [ {..., material = "m" }, "bolt" ]` named `material`), or a child: the element's
            // path.
            if key != array || array == "children" {
                let at = &self.text[span.start.min(self.text.len())..];
                let msg = if array == "children" && (inner || at.starts_with('[')) {
                    "a list where a child belongs: write each child as a shape table, `{ type = ..., ... }`".to_string()
                } else if array == "children" && at.starts_with(['"', '\'']) {
                    format!("{}; a named solid is used as `{{ use = \"NAME\" }}`", plain_struct_names(&message))
                } else {
                    plain_struct_names(&message)
                };
                return self.error(span, path, msg);
            }
        }
        let field = named.and_then(extract_backticked).unwrap_or_else(|| self.qualified(span.start, key));
        self.error(span, field, plain_struct_names(&message))
    }

    /// `key` as the path the compiler's own errors give (`shapes[1].radius`, `materials.glass.ior`,
    /// `shapes[0].transform.rotate`), where the line at `offset` is `key = ...` under a table header;
    /// else `key` itself (a key in an inline table, or under a nested list header, whose path the text
    /// does not give plainly).
    fn qualified(&self, offset: usize, key: String) -> String {
        let offset = offset.min(self.text.len());
        let line_start = self.text[..offset].rfind('\n').map_or(0, |i| i + 1);
        let line = self.text[line_start..].lines().next().unwrap_or("").trim_start();
        let first_key = line.split('=').next().unwrap_or("").trim();
        if key.is_empty() || first_key != key {
            return key;
        }
        // A key of an inline table opened on an earlier line (`checker = {`, then `b = ...`): under its key.
        let Some(open) = open_inline_tables(&self.text[self.header_end(line_start)..line_start]) else { return key };
        let key = open.into_iter().chain([key]).collect::<Vec<_>>().join(".");
        self.under_header(line_start, key)
    }

    /// The end of the last table header line before byte `line_start` (0 if none). (Byte offsets from
    /// the lines with their breaks: `\r\n` counts two.)
    fn header_end(&self, line_start: usize) -> usize {
        self.text[..line_start]
            .split_inclusive('\n')
            .scan(0, |at, l| {
                *at += l.len();
                Some((*at, l))
            })
            .filter(|(_, l)| table_header(l).is_some())
            .last()
            .map_or(0, |(end, _)| end)
    }

    /// `key`, a key of the table whose header is the last before byte `line_start`, as the path the
    /// compiler's errors give (`shapes[1].radius`, `materials.glass.ior`, `shapes[0].transform.rotate`);
    /// `key` itself where there is no header or the path is not plain (under a nested list header).
    fn under_header(&self, line_start: usize, key: String) -> String {
        let headers: Vec<(bool, String)> = self.text[..line_start].lines().filter_map(table_header).collect();
        let Some((list, name)) = headers.last() else { return key };
        // The index of the entry of list `l` that the last header lies in.
        let index = |l: &str| headers.iter().filter(|(is_list, n)| *is_list && n == l).count().checked_sub(1);
        if *list {
            return match (name.contains('.'), index(name)) {
                (false, Some(i)) => format!("{name}[{i}].{key}"),
                _ => key,
            };
        }
        // A sub-table of a list's entry (`[shapes.transform]` after `[[shapes]]`), or a plain table.
        let first = name.split('.').next().unwrap_or("");
        match index(first) {
            Some(i) => format!("{first}[{i}]{}.{key}", &name[first.len()..]),
            None => format!("{name}.{key}"),
        }
    }

    /// Where byte `offset` is an element of an array value (`children = [ {...}, "bolt" ]`: the string),
    /// its path (`shapes[0].children[1]`; arrays and inline tables opened on earlier lines counted), the
    /// array's key, and whether the element is in a list within that array (`[ [ {...} ] ]`: the path is
    /// then the list's); `None` elsewhere, or where the text before it is not plain enough to follow.
    fn element_path(&self, offset: usize) -> Option<(String, String, bool)> {
        let offset = offset.min(self.text.len());
        let line_start = self.text[..offset].rfind('\n').map_or(0, |i| i + 1);
        let mut open = open_values(&self.text[self.header_end(line_start)..offset])?;
        let inner = open.len() >= 2 && open[open.len() - 1].1.is_empty() && open[open.len() - 2].0 == '[';
        if inner && open[open.len() - 1].0 == '[' {
            open.pop();
        }
        let (c, key, _) = open.last()?;
        if *c != '[' || open[0].1.is_empty() {
            return None;
        }
        let key = key.clone();
        let mut path = String::new();
        for (c, k, i) in open {
            if !k.is_empty() {
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(&k);
            }
            if c == '[' {
                path.push_str(&format!("[{i}]"));
            }
        }
        Some((self.under_header(line_start, path), key, inner))
    }

    /// The key of the `key = value` entry that byte `offset` lies in, looking back along its own line
    /// only (a value spanning lines names no key), or the table of a header line.
    fn key_at(&self, offset: usize) -> String {
        let offset = offset.min(self.text.len());
        let bytes = self.text.as_bytes();
        let line_start = bytes[..offset].iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let line_end = bytes[offset..].iter().position(|&b| b == b'\n').map_or(bytes.len(), |i| offset + i);
        let is_key = |b: u8| b.is_ascii_alphanumeric() || b == b'_' || b == b'-';
        // A table header (`[image]` defined twice): the table's name.
        let line = self.text[line_start..line_end].trim();
        if let Some(inner) = line.strip_prefix('[') {
            let name = inner.trim_start_matches('[');
            return name.find(']').map_or(String::new(), |e| name[..e].trim().to_string());
        }
        // The span may start at the key itself (duplicate key): the bare key there, if `=` follows it.
        let key_here = bytes[offset..line_end].iter().take_while(|&&b| is_key(b)).count();
        if key_here > 0 && bytes[offset + key_here..line_end].iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'=') {
            return self.text[offset..offset + key_here].to_string();
        }
        // Else the nearest `key =` before the offset on this line, or at it (the innermost one in an
        // inline table; a misplaced `=` is reported at itself).
        let before = &bytes[line_start..(offset + 1).min(line_end)];
        for eq in (0..before.len()).rev().filter(|&i| before[i] == b'=') {
            let end = before[..eq].iter().rposition(|b| !b.is_ascii_whitespace()).map_or(0, |i| i + 1);
            let start = before[..end].iter().rposition(|&b| !is_key(b)).map_or(0, |i| i + 1);
            if start < end {
                return self.text[line_start + start..line_start + end].to_string();
            }
        }
        String::new()
    }
}

/// The indefinite article for `word` (a material, shape or light kind): "an" before a vowel sound
/// (`an emissive material`), "a" elsewhere (`a lambert material`, `a use`: a `u` that sounds as "you").
pub(crate) fn a_or_an(word: &str) -> &'static str {
    match word.as_bytes().first().map(u8::to_ascii_lowercase) {
        Some(b'a' | b'e' | b'i' | b'o') => "an",
        _ => "a",
    }
}

/// The reader's words for the file's tables ("expected struct MaterialDef", serde's name for the Rust
/// type) as what a scene writer knows them by.
fn plain_struct_names(message: &str) -> String {
    const NAMES: [(&str, &str); 9] = [
        ("SceneFile", "a scene file ([image], [camera], [materials.NAME], [[shapes]], [[lights]])"),
        ("ImageDef", "the [image] table (width, height, background)"),
        ("CameraDef", "the [camera] table (position, look_at, fov, ...)"),
        ("CheckerDef", "a checker table ({ a = [r, g, b], b = [r, g, b], scale = s })"),
        ("MaterialDef", "a material table ([materials.NAME] with type = \"lambert\", ...)"),
        ("TransformDef", "a transform table ({ scale = [...], rotate = [...], translate = [...] })"),
        ("ShapeDef", "a shape table ([[shapes]] with type = \"sphere\", ...)"),
        ("LightDef", "a light table ([[lights]] with type = \"point\", ...)"),
        ("Profile", "a profile table (name, spp, strategies, ...)"),
    ];
    let mut out = message.to_string();
    for (rust, plain) in NAMES {
        out = out.replace(&format!("expected struct {rust}"), &format!("expected {plain}"));
    }
    out
}

fn extract_backticked(s: &str) -> Option<String> {
    let a = s.find('`')?;
    let b = s[a + 1..].find('`')?;
    Some(s[a + 1..a + 1 + b].to_string())
}

/// Read a file as UTF-8 text, with an `InputError` for unreadable (line 0: no position) or non-UTF-8
/// (at the first bad byte) files.
pub fn read_text(path: &Path) -> Result<String, InputError> {
    let err = |line: usize, message: String| InputError { file: path.to_path_buf(), line, column: 1, field: String::new(), message };
    // Read at most one byte past the limit: a huge file (or /dev/zero) is refused without being read.
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| std::io::Read::read_to_end(&mut std::io::Read::take(f, MAX_INPUT_BYTES as u64 + 1), &mut bytes))
        .map_err(|e| err(0, format!("cannot read file: {e}")))?;
    if bytes.len() > MAX_INPUT_BYTES {
        return Err(err(0, format!("file is larger than the limit of {MAX_INPUT_BYTES} bytes (16 MiB)")));
    }
    String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        err(line, format!("file is not valid UTF-8 (byte {})", e.utf8_error().valid_up_to()))
    })
}

/// Scene files larger than this are refused before parsing (protects the machine).
pub const MAX_INPUT_BYTES: usize = 16 << 20;

/// A table header line, `[a.b]` or `[[a]]` (spaces around names and dots dropped, quoted names
/// unquoted: `[["shapes"]]` is `shapes`; a trailing comment allowed): whether it is a list's, and its
/// dotted name. Other lines (an array continued over lines, `[0.5, 0.5],`) are not headers, nor are
/// headers this cannot name plainly (a quoted name with an escape or a dot in it).
pub(crate) fn table_header(line: &str) -> Option<(bool, String)> {
    let t = line.trim_start();
    let (list, mut rest) = match t.strip_prefix("[[") {
        Some(r) => (true, r),
        None => (false, t.strip_prefix('[')?),
    };
    let mut parts: Vec<&str> = Vec::new();
    loop {
        rest = rest.trim_start();
        let (part, after) = if let Some(r) = rest.strip_prefix('"') {
            let end = r.find('"')?;
            (&r[..end], &r[end + 1..])
        } else if let Some(r) = rest.strip_prefix('\'') {
            let end = r.find('\'')?;
            (&r[..end], &r[end + 1..])
        } else {
            let end = rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '-')).unwrap_or(rest.len());
            (&rest[..end], &rest[end..])
        };
        if part.is_empty() || part.contains(['.', '\\', '"', '\'']) {
            return None;
        }
        parts.push(part);
        let after = after.trim_start();
        if let Some(r) = after.strip_prefix('.') {
            rest = r;
            continue;
        }
        let tail = after.strip_prefix(if list { "]]" } else { "]" })?.trim_start();
        return (tail.is_empty() || tail.starts_with('#')).then(|| (list, parts.join(".")));
    }
}

/// The keys of the inline tables still open at the end of `text` (`checker = {` on an earlier line:
/// `["checker"]`, outermost first), or `None` where the text is inside an array (whose element has no
/// name) or holds what this does not follow (a multi-line string).
fn open_inline_tables(text: &str) -> Option<Vec<String>> {
    let open = open_values(text)?;
    open.iter().all(|(c, k, _)| *c == '{' && !k.is_empty()).then(|| open.into_iter().map(|(_, k, _)| k).collect())
}

/// The inline tables and arrays still open at the end of `text`, outermost first: each bracket, the key
/// before it (empty for an element of an array) and, for an array, the index of the element the text
/// ends in; `None` where the text holds what this does not follow (a multi-line string, more closing
/// than opening brackets). Strings and comments are skipped.
fn open_values(text: &str) -> Option<Vec<(char, String, usize)>> {
    let mut open: Vec<(char, String, usize)> = Vec::new();
    // The text since the last `{`, `,` or line break: where the key before a `{` lies.
    let mut since = String::new();
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '"' | '\'' => {
                let mut body = String::new();
                let mut escaped = false;
                loop {
                    let d = chars.next()?;
                    if c == '"' && escaped {
                        escaped = false;
                    } else if c == '"' && d == '\\' {
                        escaped = true;
                    } else if d == c {
                        break;
                    } else if d == '\n' {
                        return None;
                    }
                    body.push(d);
                }
                if body.is_empty() && chars.peek() == Some(&c) {
                    return None;
                }
                since.push_str(&body);
            }
            '#' => {
                for d in chars.by_ref() {
                    if d == '\n' {
                        break;
                    }
                }
                since.clear();
            }
            '{' => {
                // (An array's element has no key: it names nothing, should the text end inside it.)
                let key = since.trim_end().strip_suffix('=').map_or(String::new(), |k| k.trim().to_string());
                open.push(('{', key, 0));
                since.clear();
            }
            '[' => {
                let key = since.trim_end().strip_suffix('=').map_or(String::new(), |k| k.trim().to_string());
                open.push(('[', key, 0));
                since.clear();
            }
            '}' | ']' => {
                open.pop()?;
                since.clear();
            }
            ',' => {
                if let Some(('[', _, i)) = open.last_mut() {
                    *i += 1;
                }
                since.clear();
            }
            '\n' => since.clear(),
            _ => since.push(c),
        }
    }
    Some(open)
}
