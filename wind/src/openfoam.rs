//! OpenFOAM ASCII vector fields: the cell centres `C` and the velocity `U` of a case that a
//! user computed elsewhere, read from the text of their files.
//!
//! A case's cell centres come from `postProcess -func writeCellCentres` (the field `C`,
//! metres, in the case's frame); its velocity is the solver's `U` (m/s, same frame). Both
//! are `volVectorField` files:
//!
//! ```text
//! FoamFile { version 2.0; format ascii; class volVectorField; object U; }
//! dimensions      [0 1 -1 0 0 0 0];
//! internalField   nonuniform List<vector> 2 ( (1 0 0) (0.5 0.1 0) );
//! boundaryField   { ... }
//! ```
//!
//! Only the header, `dimensions` and `internalField` are read; `boundaryField` is not (the
//! cells are what a wind grid is sampled from). The internal field may be
//! `nonuniform List<vector> N ( (x y z) ... )`, the compact `nonuniform List<vector> N{(x y z)}`
//! OpenFOAM writes for a list of equal values, or `uniform (x y z)`, which holds no cell
//! count: [`parse_vector_field_cells`] takes it from the caller (usually `C`'s length).
//!
//! # Errors
//! Every error names the file (as the caller gave it) and, where there is one, the line
//! (1-based) and what was expected. Binary files are refused with the fix (`writeFormat
//! ascii`), so are non-finite components (`nan`, `inf`), a list count that disagrees with
//! its entries and, in [`parse_case_fields`], `C` and `U` of different lengths or
//! dimensions that are not metres and metres per second.
//!
//! # Caveats
//! Compressed files (`U.gz`, `writeCompression on`) are the caller's to decompress; macros
//! (`#include`, `$var`) in the internal field are refused, not expanded.

/// Why an OpenFOAM field file cannot be read. `file` is the name the caller gave.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FoamError {
    /// The text does not follow the OpenFOAM format where it matters.
    #[error("{file}:{line}: expected {expected}, found {found}")]
    Syntax { file: String, line: usize, expected: String, found: String },
    /// The file has no `FoamFile { ... }` header at its start.
    #[error(
        "{file}:{line}: expected the OpenFOAM header `FoamFile {{ ... }}`, found {found}: is this an OpenFOAM field file?"
    )]
    NoHeader { file: String, line: usize, found: String },
    /// The header says `format binary`.
    #[error(
        "{file}:{line}: the field is written in binary (`format binary`); set `writeFormat ascii;` in the case's system/controlDict and rewrite the fields (e.g. `foamFormatConvert`)"
    )]
    Binary { file: String, line: usize },
    /// The header's class is not `volVectorField` (e.g. the pressure `p`, a `volScalarField`).
    #[error("{file}:{line}: the field's class is {class}, expected volVectorField (cell centres C or velocity U)")]
    WrongClass { file: String, line: usize, class: String },
    /// The file has no `internalField` entry.
    #[error(
        "{file}: no `internalField` entry: expected `internalField nonuniform List<vector> N (...)` or `internalField uniform (x y z)`"
    )]
    NoInternalField { file: String },
    /// A vector component is NaN or infinite.
    #[error("{file}:{line}: {} has a non-finite component ({value}): the solver diverged or the field is damaged", entry_name(.index))]
    NonFinite { file: String, line: usize, index: Option<usize>, value: String },
    /// A list's declared count disagrees with its entries.
    #[error("{file}:{line}: the list declares {declared} entries but holds {found}")]
    CountMismatch { file: String, line: usize, declared: usize, found: usize },
    /// `internalField uniform` without a cell count to expand it to.
    #[error(
        "{file}:{line}: `internalField uniform` does not say how many cells the case has; read the cell centres C first and pass their count"
    )]
    UniformNeedsCellCount { file: String, line: usize },
    /// A field's number of cells differs from the case's (the other field's).
    #[error(
        "{file} has {len} cells but {other_file} has {other_len}: the two fields are not of the same mesh (or not of the same time)"
    )]
    DifferentCells { file: String, len: usize, other_file: String, other_len: usize },
    /// `dimensions` are not those of the quantity expected.
    #[error("{file}:{line}: dimensions {found} are not those of {expected}")]
    WrongDimensions { file: String, line: usize, expected: String, found: String },
}

fn entry_name(index: &Option<usize>) -> String {
    match index {
        Some(i) => format!("entry {i} (0-based) of the internal field"),
        None => "the uniform internal field".to_string(),
    }
}

/// The cell values of the `volVectorField` `text` (file name `file`, for errors), whose
/// internal field is a nonuniform list. Components are as written: metres for `C`, m/s
/// for `U`, in the case's Cartesian frame.
///
/// # Errors
/// See [`FoamError`]; `internalField uniform` is [`FoamError::UniformNeedsCellCount`]
/// (use [`parse_vector_field_cells`]).
pub fn parse_vector_field(file: &str, text: &str) -> Result<Vec<[f64; 3]>, FoamError> {
    Ok(parse(file, text, None)?.values)
}

/// As [`parse_vector_field`], for a case of `cells` cells: a `uniform` internal field is
/// expanded to `cells` values, and a nonuniform one must have `cells` values.
///
/// # Errors
/// See [`FoamError`]; a nonuniform list of another length is [`FoamError::DifferentCells`].
pub fn parse_vector_field_cells(
    file: &str,
    text: &str,
    cells: usize,
    cells_from: &str,
) -> Result<Vec<[f64; 3]>, FoamError> {
    let values = parse(file, text, Some(cells))?.values;
    check_same_cells(cells_from, cells, file, values.len())?;
    Ok(values)
}

/// Refuses two fields of different lengths: `C` and `U` must describe the same cells.
///
/// # Errors
/// [`FoamError::DifferentCells`] naming both files and lengths.
pub fn check_same_cells(c_file: &str, c_len: usize, u_file: &str, u_len: usize) -> Result<(), FoamError> {
    if c_len == u_len {
        return Ok(());
    }
    Err(FoamError::DifferentCells {
        file: c_file.to_string(),
        len: c_len,
        other_file: u_file.to_string(),
        other_len: u_len,
    })
}

/// A case's cell centres (m) and velocities (m/s), same length, same order.
#[derive(Clone, Debug, PartialEq)]
pub struct CaseFields {
    pub centres_m: Vec<[f64; 3]>,
    pub velocity_mps: Vec<[f64; 3]>,
}

/// Reads a case's `C` and `U` together: `C` must be a nonuniform list with the dimensions
/// of a length, `U` (uniform or not) one value per cell with those of a velocity. Files
/// without `dimensions` are accepted (the check is to catch swapped files).
///
/// # Errors
/// Any of either file's [`FoamError`]s; [`FoamError::DifferentCells`] when `U` has another
/// number of cells than `C`; [`FoamError::WrongDimensions`] when `C` is not in metres or
/// `U` not in metres per second.
pub fn parse_case_fields(c_file: &str, c_text: &str, u_file: &str, u_text: &str) -> Result<CaseFields, FoamError> {
    let c = parse(c_file, c_text, None)?;
    check_dimensions(c_file, &c, [0.0, 1.0, 0.0], "a length [0 1 0 0 0 0 0] (m): is this the cell centres C?")?;
    let u = parse(u_file, u_text, Some(c.values.len()))?;
    check_dimensions(u_file, &u, [0.0, 1.0, -1.0], "a velocity [0 1 -1 0 0 0 0] (m/s): is this the velocity U?")?;
    check_same_cells(c_file, c.values.len(), u_file, u.values.len())?;
    Ok(CaseFields { centres_m: c.values, velocity_mps: u.values })
}

/// OpenFOAM's dimension exponents in order: mass, length, time, temperature, moles,
/// current, luminous intensity. The first three decide between C, U and the rest.
fn check_dimensions(file: &str, field: &Parsed, mass_length_time: [f64; 3], expected: &str) -> Result<(), FoamError> {
    let Some((line, dims)) = &field.dimensions else {
        return Ok(());
    };
    let others_zero = dims.iter().skip(3).all(|d| *d == 0.0);
    if dims.len() >= 3 && dims[..3] == mass_length_time && others_zero {
        return Ok(());
    }
    let found = dims.iter().map(|d| format!("{d}")).collect::<Vec<_>>().join(" ");
    Err(FoamError::WrongDimensions {
        file: file.to_string(),
        line: *line,
        expected: expected.to_string(),
        found: format!("[{found}]"),
    })
}

/// What a field file holds that matters here.
#[derive(Debug)]
struct Parsed {
    /// `dimensions [..]` with its line, when written as plain exponents.
    dimensions: Option<(usize, Vec<f64>)>,
    values: Vec<[f64; 3]>,
}

/// A lexical token of an OpenFOAM dictionary.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Token<'a> {
    /// One of `( ) { } [ ] ;`.
    Punct(u8),
    /// A run of other non-blank characters: keywords, numbers, `List<vector>`, `#include`.
    Word(&'a str),
    /// A double-quoted string, without its quotes.
    Str(&'a str),
    Eof,
}

impl Token<'_> {
    /// How an error message shows the token.
    fn describe(&self) -> String {
        match self {
            Token::Punct(c) => format!("`{}`", *c as char),
            Token::Word(w) => format!("`{}`", truncate(w)),
            // Debug: quotes, and line breaks escaped, so the error stays one line.
            Token::Str(s) => format!("{:?}", truncate(s)),
            Token::Eof => "the end of the file".to_string(),
        }
    }
}

fn truncate(s: &str) -> &str {
    match s.char_indices().nth(40) {
        Some((i, _)) => &s[..i],
        None => s,
    }
}

/// Splits the text into tokens, skipping blanks and comments, counting lines.
struct Lexer<'a> {
    file: &'a str,
    text: &'a str,
    pos: usize,
    line: usize,
}

impl<'a> Lexer<'a> {
    fn new(file: &'a str, text: &'a str) -> Self {
        Lexer { file, text, pos: 0, line: 1 }
    }

    /// The next token and the line it starts on.
    fn next(&mut self) -> Result<(Token<'a>, usize), FoamError> {
        let bytes = self.text.as_bytes();
        // Blanks and comments.
        loop {
            match bytes.get(self.pos) {
                Some(b'\n') => {
                    self.line += 1;
                    self.pos += 1;
                }
                Some(c) if c.is_ascii_whitespace() => self.pos += 1,
                Some(b'/') if bytes.get(self.pos + 1) == Some(&b'/') => {
                    while let Some(c) = bytes.get(self.pos) {
                        if *c == b'\n' {
                            break;
                        }
                        self.pos += 1;
                    }
                }
                Some(b'/') if bytes.get(self.pos + 1) == Some(&b'*') => {
                    let start_line = self.line;
                    self.pos += 2;
                    loop {
                        match bytes.get(self.pos) {
                            None => {
                                return Err(self.syntax(start_line, "`*/` closing the comment", "the end of the file"));
                            }
                            Some(b'*') if bytes.get(self.pos + 1) == Some(&b'/') => {
                                self.pos += 2;
                                break;
                            }
                            Some(b'\n') => {
                                self.line += 1;
                                self.pos += 1;
                            }
                            Some(_) => self.pos += 1,
                        }
                    }
                }
                _ => break,
            }
        }
        let line = self.line;
        let Some(&c) = bytes.get(self.pos) else {
            return Ok((Token::Eof, line));
        };
        if b"(){}[];".contains(&c) {
            self.pos += 1;
            return Ok((Token::Punct(c), line));
        }
        if c == b'"' {
            let start = self.pos + 1;
            let mut i = start;
            loop {
                match bytes.get(i) {
                    None => return Err(self.syntax(line, "`\"` closing the string", "the end of the file")),
                    Some(b'\\') => i += 2,
                    Some(b'"') => break,
                    Some(b'\n') => {
                        self.line += 1;
                        i += 1;
                    }
                    Some(_) => i += 1,
                }
            }
            self.pos = i + 1;
            return Ok((Token::Str(&self.text[start..i]), line));
        }
        let start = self.pos;
        while let Some(&c) = bytes.get(self.pos) {
            if c.is_ascii_whitespace() || b"(){}[];\"".contains(&c) {
                break;
            }
            self.pos += 1;
        }
        Ok((Token::Word(&self.text[start..self.pos]), line))
    }

    fn syntax(&self, line: usize, expected: &str, found: &str) -> FoamError {
        FoamError::Syntax {
            file: self.file.to_string(),
            line,
            expected: expected.to_string(),
            found: found.to_string(),
        }
    }

    /// The next token, which must be the punctuation `c`.
    fn expect_punct(&mut self, c: u8, expected: &str) -> Result<usize, FoamError> {
        match self.next()? {
            (Token::Punct(p), line) if p == c => Ok(line),
            (t, line) => Err(self.syntax(line, expected, &t.describe())),
        }
    }

    /// The next token, which must be a word.
    fn expect_word(&mut self, expected: &str) -> Result<(&'a str, usize), FoamError> {
        match self.next()? {
            (Token::Word(w), line) => Ok((w, line)),
            (t, line) => Err(self.syntax(line, expected, &t.describe())),
        }
    }

    /// Skips an entry's value up to its closing `;` (or a whole `{ ... }` dictionary).
    fn skip_value(&mut self) -> Result<(), FoamError> {
        let mut depth = 0usize;
        loop {
            let (t, line) = self.next()?;
            match t {
                Token::Punct(b'(' | b'[' | b'{') => depth += 1,
                Token::Punct(b')' | b']' | b'}') => {
                    if depth == 0 {
                        return Err(self.syntax(line, "a value ending with `;`", &t.describe()));
                    }
                    depth -= 1;
                    // A sub-dictionary `name { ... }` ends with its brace.
                    if depth == 0 && t == Token::Punct(b'}') {
                        return Ok(());
                    }
                }
                Token::Punct(b';') if depth == 0 => return Ok(()),
                Token::Eof => return Err(self.syntax(line, "a value ending with `;`", "the end of the file")),
                _ => {}
            }
        }
    }
}

/// Reads the header, `dimensions` and `internalField` of a volVectorField. With `cells`,
/// a uniform internal field is expanded to that many values.
fn parse(file: &str, text: &str, cells: Option<usize>) -> Result<Parsed, FoamError> {
    let mut lex = Lexer::new(file, text);
    parse_header(&mut lex)?;
    let mut dimensions = None;
    loop {
        let (t, line) = lex.next()?;
        match t {
            Token::Word("internalField") => {
                let values = parse_internal_field(&mut lex, cells)?;
                return Ok(Parsed { dimensions, values });
            }
            Token::Word("dimensions") => dimensions = parse_dimensions(&mut lex)?.map(|d| (line, d)),
            Token::Word(_) => lex.skip_value()?,
            Token::Eof => return Err(FoamError::NoInternalField { file: file.to_string() }),
            t => return Err(lex.syntax(line, "a keyword", &t.describe())),
        }
    }
}

/// `FoamFile { ... }`: refuses binary files and classes other than volVectorField.
fn parse_header(lex: &mut Lexer) -> Result<(), FoamError> {
    let file = lex.file.to_string();
    match lex.next()? {
        (Token::Word("FoamFile"), _) => {}
        (t, line) => return Err(FoamError::NoHeader { file, line, found: t.describe() }),
    }
    lex.expect_punct(b'{', "`{` opening the FoamFile header")?;
    let mut class = None;
    loop {
        let (t, line) = lex.next()?;
        let key = match t {
            Token::Punct(b'}') => break,
            Token::Word(w) => w,
            t => return Err(lex.syntax(line, "a header keyword or `}`", &t.describe())),
        };
        let (value, value_line) = match lex.next()? {
            (Token::Word(w) | Token::Str(w), l) => (w, l),
            (t, l) => return Err(lex.syntax(l, &format!("the value of `{key}`"), &t.describe())),
        };
        lex.expect_punct(b';', &format!("`;` after the value of `{key}`"))?;
        match key {
            "format" if value == "binary" => return Err(FoamError::Binary { file, line: value_line }),
            "format" if value != "ascii" => {
                return Err(lex.syntax(value_line, "`format ascii`", &format!("`format {}`", truncate(value))));
            }
            "class" => class = Some((value, value_line)),
            _ => {}
        }
    }
    match class {
        Some(("volVectorField", _)) => Ok(()),
        Some((other, line)) => Err(FoamError::WrongClass { file, line, class: other.to_string() }),
        None => Err(FoamError::WrongClass { file, line: lex.line, class: "missing from the header".to_string() }),
    }
}

/// `[0 1 -1 0 0 0 0];` as numbers; `None` for named units (`[m/s]`), which are left unchecked.
fn parse_dimensions(lex: &mut Lexer) -> Result<Option<Vec<f64>>, FoamError> {
    let (t, line) = lex.next()?;
    if t != Token::Punct(b'[') {
        return Err(lex.syntax(line, "`[` opening the dimensions", &t.describe()));
    }
    let mut exponents = Some(Vec::new());
    loop {
        let (t, line) = lex.next()?;
        match t {
            Token::Punct(b']') => break,
            Token::Word(w) => match (w.parse::<f64>(), exponents.as_mut()) {
                (Ok(v), Some(e)) => e.push(v),
                _ => exponents = None,
            },
            t => return Err(lex.syntax(line, "dimension exponents and `]`", &t.describe())),
        }
    }
    lex.expect_punct(b';', "`;` after the dimensions")?;
    Ok(exponents)
}

/// After `internalField`: `uniform (x y z);`, `nonuniform List<vector> N (...);`,
/// `nonuniform List<vector> N{(x y z)};` or `nonuniform List<vector> (...);`.
fn parse_internal_field(lex: &mut Lexer, cells: Option<usize>) -> Result<Vec<[f64; 3]>, FoamError> {
    let (kind, kind_line) = lex.expect_word("`uniform` or `nonuniform` after internalField")?;
    match kind {
        "uniform" => {
            let value = parse_vector(lex, None)?;
            lex.expect_punct(b';', "`;` after the uniform internal field")?;
            match cells {
                Some(n) => Ok(vec![value; n]),
                None => Err(FoamError::UniformNeedsCellCount { file: lex.file.to_string(), line: kind_line }),
            }
        }
        "nonuniform" => {
            let (list_type, line) = lex.expect_word("`List<vector>` after nonuniform")?;
            if list_type != "List<vector>" {
                return Err(lex.syntax(line, "`List<vector>` (a vector field)", &format!("`{}`", truncate(list_type))));
            }
            let values = parse_list(lex, cells)?;
            lex.expect_punct(b';', "`;` after the internal field's list")?;
            Ok(values)
        }
        other => Err(lex.syntax(
            kind_line,
            "`uniform` or `nonuniform` after internalField",
            &format!("`{}`", truncate(other)),
        )),
    }
}

/// The most entries a compact `N{v}` list expands to when the case's cell count is not known
/// (240 MB): a damaged `N` must not allocate without bound.
const MAX_COMPACT_ENTRIES: usize = 10_000_000;

/// `N ( v0 v1 ... )`, `N{v}` or `( v0 ... )`, each v a `(x y z)`. `cells`: the case's cell
/// count when known; a compact `N{v}` must then declare exactly that many entries.
fn parse_list(lex: &mut Lexer, cells: Option<usize>) -> Result<Vec<[f64; 3]>, FoamError> {
    let (t, count_line) = lex.next()?;
    let declared = match t {
        Token::Word(w) => match w.parse::<usize>() {
            Ok(n) => Some(n),
            Err(_) => return Err(lex.syntax(count_line, "the list's entry count", &t.describe())),
        },
        Token::Punct(b'(') => None,
        t => return Err(lex.syntax(count_line, "the list's entry count or `(`", &t.describe())),
    };
    if let Some(n) = declared {
        let (t, line) = lex.next()?;
        match t {
            Token::Punct(b'(') => {}
            // OpenFOAM's compact form for a list of equal values: N{value}.
            Token::Punct(b'{') => {
                let value = parse_vector(lex, None)?;
                lex.expect_punct(b'}', "`}` closing the uniform list")?;
                return match cells {
                    Some(c) if c != n => Err(FoamError::CountMismatch {
                        file: lex.file.to_string(),
                        line: count_line,
                        declared: n,
                        found: c,
                    }),
                    None if n > MAX_COMPACT_ENTRIES => Err(lex.syntax(
                        count_line,
                        "a compact list `N{(x y z)}` of at most 10000000 entries",
                        &n.to_string(),
                    )),
                    _ => Ok(vec![value; n]),
                };
            }
            t => return Err(lex.syntax(line, "`(` opening the list", &t.describe())),
        }
    }
    // Cap the reservation: a damaged count must not allocate gigabytes; a vector takes at
    // least 7 bytes of text, `(0 0 0)`.
    let mut values = Vec::with_capacity(declared.unwrap_or(0).min(lex.text.len() / 7));
    loop {
        let (t, line) = lex.next()?;
        match t {
            Token::Punct(b')') => break,
            Token::Punct(b'(') => values.push(parse_vector_body(lex, Some(values.len()), line)?),
            t => return Err(lex.syntax(line, "`(x y z)` or `)` closing the list", &t.describe())),
        }
    }
    match declared {
        Some(n) if n != values.len() => Err(FoamError::CountMismatch {
            file: lex.file.to_string(),
            line: count_line,
            declared: n,
            found: values.len(),
        }),
        _ => Ok(values),
    }
}

/// `(x y z)`; `index` is the entry's index in its list, for errors.
fn parse_vector(lex: &mut Lexer, index: Option<usize>) -> Result<[f64; 3], FoamError> {
    let line = lex.expect_punct(b'(', "`(` opening a vector `(x y z)`")?;
    parse_vector_body(lex, index, line)
}

/// `x y z)` after a vector's `(`.
fn parse_vector_body(lex: &mut Lexer, index: Option<usize>, open_line: usize) -> Result<[f64; 3], FoamError> {
    let mut v = [0.0; 3];
    for (axis, slot) in v.iter_mut().enumerate() {
        let (t, line) = lex.next()?;
        let Token::Word(w) = t else {
            let expected = format!("component {} of a vector `(x y z)` (its `(` on line {open_line})", axis + 1);
            return Err(lex.syntax(line, &expected, &t.describe()));
        };
        let value = parse_number(w);
        match value {
            Some(x) if x.is_finite() => *slot = x,
            Some(_) => {
                return Err(FoamError::NonFinite {
                    file: lex.file.to_string(),
                    line,
                    index,
                    value: truncate(w).to_string(),
                });
            }
            None => return Err(lex.syntax(line, "a number", &t.describe())),
        }
    }
    let (t, line) = lex.next()?;
    if t != Token::Punct(b')') {
        let expected = format!("`)` closing the vector after 3 components (its `(` on line {open_line})");
        return Err(lex.syntax(line, &expected, &t.describe()));
    }
    Ok(v)
}

/// A number as C's strtod reads OpenFOAM's output, including `nan`, `-nan`, `inf`
/// (which Rust's parser may not accept with a sign); `None` when it is not one.
fn parse_number(word: &str) -> Option<f64> {
    if let Ok(x) = word.parse::<f64>() {
        return Some(x);
    }
    let unsigned = word.strip_prefix(['-', '+']).unwrap_or(word).to_ascii_lowercase();
    match unsigned.as_str() {
        "nan" | "inf" | "infinity" => Some(f64::NAN),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A volVectorField file with `internal` after `internalField`.
    fn field(class: &str, dims: &str, internal: &str) -> String {
        format!(
            "/*--------------------------------*- C++ -*----------------------------------*\\\n\
             | =========                 |                                                 |\n\
             \\*---------------------------------------------------------------------------*/\n\
             FoamFile\n{{\n    version     2.0;\n    format      ascii;\n    class       {class};\n    \
             arch        \"LSB;label=32;scalar=64\";\n    location    \"1000\";\n    object      U;\n}}\n\
             // * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * //\n\n\
             dimensions      {dims};\n\n\
             internalField   {internal}\n\n\
             boundaryField\n{{\n    inlet\n    {{\n        type            fixedValue;\n        \
             value           uniform (1 0 0);\n    }}\n}}\n"
        )
    }

    fn u(internal: &str) -> String {
        field("volVectorField", "[0 1 -1 0 0 0 0]", internal)
    }

    fn c(internal: &str) -> String {
        field("volVectorField", "[0 1 0 0 0 0 0]", internal)
    }

    #[test]
    fn nonuniform_list_is_read_in_order() {
        let text = u("nonuniform List<vector> \n3\n(\n(1 2 3)\n(-0.5 1e-3 4.5E+2)\n(0 0 -7)\n)\n;");
        let v = parse_vector_field("0/U", &text).unwrap();
        assert_eq!(v, vec![[1.0, 2.0, 3.0], [-0.5, 1e-3, 450.0], [0.0, 0.0, -7.0]]);
    }

    #[test]
    fn short_list_on_one_line_and_list_without_count() {
        let one_line = u("nonuniform List<vector> 2((1 0 0) (0 1 0));");
        assert_eq!(parse_vector_field("U", &one_line).unwrap(), vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let no_count = u("nonuniform List<vector> ((1 0 0));");
        assert_eq!(parse_vector_field("U", &no_count).unwrap(), vec![[1.0, 0.0, 0.0]]);
    }

    #[test]
    fn compact_list_of_equal_values_is_expanded() {
        let text = u("nonuniform List<vector> 4{(2 0 1)};");
        assert_eq!(parse_vector_field("U", &text).unwrap(), vec![[2.0, 0.0, 1.0]; 4]);
    }

    #[test]
    fn a_compact_list_s_count_is_bounded_before_it_is_expanded() {
        // Found by fuzz/openfoam: 728888888888888888{(..)} asked for 1.7e19 bytes.
        let huge = u("nonuniform List<vector> 728888888888888888{(7 0 0)};");
        let err = parse_vector_field("U", &huge).unwrap_err().to_string();
        assert!(err.contains("at most 10000000 entries"), "{err}");
        let mut lex = Lexer::new("U", "nonuniform List<vector> 5{(1 0 0)};");
        let err = parse_internal_field(&mut lex, Some(4)).unwrap_err();
        assert!(matches!(err, FoamError::CountMismatch { declared: 5, found: 4, .. }), "{err}");
    }

    #[test]
    fn comments_are_skipped_everywhere() {
        let text =
            u("nonuniform /* a block\ncomment */ List<vector> // the type\n2 ( (1 /* x */ 2 3) // one\n(4 5 6) );");
        assert_eq!(parse_vector_field("U", &text).unwrap(), vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    }

    #[test]
    fn uniform_field_takes_the_cell_count_from_the_caller() {
        let text = u("uniform (10 0 -1);");
        assert_eq!(parse_vector_field_cells("0/U", &text, 3, "0/C").unwrap(), vec![[10.0, 0.0, -1.0]; 3]);
        let err = parse_vector_field("0/U", &text).unwrap_err();
        assert!(matches!(err, FoamError::UniformNeedsCellCount { ref file, line: 17 } if file == "0/U"), "{err:?}");
    }

    #[test]
    fn nonuniform_field_of_another_length_than_the_mesh_is_refused() {
        let text = u("nonuniform List<vector> 2((1 0 0) (0 1 0));");
        let err = parse_vector_field_cells("1000/U", &text, 3, "1000/C").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("1000/C has 3 cells") && msg.contains("1000/U has 2"), "{msg}");
    }

    #[test]
    fn binary_format_is_refused_with_the_fix() {
        let text = u("nonuniform List<vector> 1((1 0 0));").replace("format      ascii", "format      binary");
        let err = parse_vector_field("case/1000/U", &text).unwrap_err();
        assert_eq!(err, FoamError::Binary { file: "case/1000/U".into(), line: 7 });
        assert!(err.to_string().contains("writeFormat ascii"), "{err}");
    }

    #[test]
    fn scalar_field_is_refused_by_class() {
        let text = field("volScalarField", "[0 2 -2 0 0 0 0]", "uniform 0;");
        let err = parse_vector_field("0/p", &text).unwrap_err();
        assert_eq!(err, FoamError::WrongClass { file: "0/p".into(), line: 8, class: "volScalarField".into() });
    }

    #[test]
    fn scalar_list_is_refused_by_type() {
        let text = u("nonuniform List<scalar> 2(1 2);");
        let err = parse_vector_field("U", &text).unwrap_err();
        assert!(matches!(&err, FoamError::Syntax { line: 17, found, .. } if found == "`List<scalar>`"), "{err:?}");
    }

    #[test]
    fn missing_header_and_missing_internal_field_are_named() {
        let err = parse_vector_field("U", "internalField uniform (0 0 0);").unwrap_err();
        assert!(matches!(err, FoamError::NoHeader { line: 1, .. }), "{err:?}");
        let text =
            "FoamFile { format ascii; class volVectorField; }\ndimensions [0 1 -1 0 0 0 0];\nboundaryField { }\n";
        assert_eq!(parse_vector_field("U", text).unwrap_err(), FoamError::NoInternalField { file: "U".into() });
    }

    #[test]
    fn non_finite_component_names_entry_and_line() {
        for bad in ["nan", "-nan", "NaN", "inf", "-inf", "1e999"] {
            let text = u(&format!("nonuniform List<vector> 3\n(\n(1 0 0)\n(0 1 0)\n(0 {bad} 0)\n);"));
            let err = parse_vector_field("2000/U", &text).unwrap_err();
            assert_eq!(
                err,
                FoamError::NonFinite { file: "2000/U".into(), line: 21, index: Some(2), value: bad.into() },
                "{bad}"
            );
            assert!(err.to_string().starts_with("2000/U:21: entry 2 (0-based)"), "{err}");
        }
        let err = parse_vector_field_cells("U", &u("uniform (nan 0 0);"), 2, "C").unwrap_err();
        assert!(matches!(err, FoamError::NonFinite { index: None, line: 17, .. }), "{err:?}");
    }

    #[test]
    fn count_that_disagrees_with_the_entries_is_refused() {
        let text = u("nonuniform List<vector> 3\n(\n(1 0 0)\n(0 1 0)\n);");
        let err = parse_vector_field("U", &text).unwrap_err();
        assert_eq!(err, FoamError::CountMismatch { file: "U".into(), line: 17, declared: 3, found: 2 });
    }

    #[test]
    fn truncated_file_and_short_vector_name_the_line() {
        let truncated = u("nonuniform List<vector> 3\n(\n(1 0 0)\n(0 1");
        let truncated = &truncated[..truncated.find("(0 1").unwrap() + 4];
        let err = parse_vector_field("U", truncated).unwrap_err();
        assert!(matches!(&err, FoamError::Syntax { line: 20, found, .. } if found == "the end of the file"), "{err:?}");
        let short = u("nonuniform List<vector> 1\n(\n(1 0)\n);");
        let err = parse_vector_field("U", &short).unwrap_err();
        assert!(matches!(&err, FoamError::Syntax { line: 19, found, .. } if found == "`)`"), "{err:?}");
        assert!(err.to_string().starts_with("U:19: expected component 3 of a vector"), "{err}");
        let word = u("nonuniform List<vector> 1\n(\n(1 zero 0)\n);");
        let err = parse_vector_field("U", &word).unwrap_err();
        assert!(err.to_string().starts_with("U:19: expected a number, found `zero`"), "{err}");
    }

    #[test]
    fn unterminated_block_comment_is_an_error() {
        let text =
            "FoamFile { format ascii; class volVectorField; }\n/* never\nclosed\ninternalField uniform (0 0 0);\n";
        let err = parse_vector_field("U", text).unwrap_err();
        assert_eq!(err.to_string(), "U:2: expected `*/` closing the comment, found the end of the file");
    }

    #[test]
    fn case_fields_are_read_together() {
        let cs = c("nonuniform List<vector> 2((0.5 0.5 0.5) (1.5 0.5 0.5));");
        let us = u("uniform (3 0 0);");
        let f = parse_case_fields("1000/C", &cs, "1000/U", &us).unwrap();
        assert_eq!(f.centres_m, vec![[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]]);
        assert_eq!(f.velocity_mps, vec![[3.0, 0.0, 0.0]; 2]);
    }

    #[test]
    fn case_fields_of_different_lengths_are_refused() {
        let cs = c("nonuniform List<vector> 2((0.5 0.5 0.5) (1.5 0.5 0.5));");
        let us = u("nonuniform List<vector> 3((1 0 0) (1 0 0) (1 0 0));");
        let err = parse_case_fields("1000/C", &cs, "1000/U", &us).unwrap_err();
        assert_eq!(
            err,
            FoamError::DifferentCells { file: "1000/C".into(), len: 2, other_file: "1000/U".into(), other_len: 3 }
        );
        assert_eq!(check_same_cells("C", 5, "U", 5), Ok(()));
    }

    #[test]
    fn swapped_c_and_u_are_caught_by_their_dimensions() {
        let cs = c("nonuniform List<vector> 1((0.5 0.5 0.5));");
        let us = u("nonuniform List<vector> 1((1 0 0));");
        let err = parse_case_fields("U", &us, "C", &cs).unwrap_err();
        assert!(
            matches!(&err, FoamError::WrongDimensions { file, line: 15, found, .. }
            if file == "U" && found == "[0 1 -1 0 0 0 0]"),
            "{err:?}"
        );
        assert!(err.to_string().contains("is this the cell centres C?"), "{err}");
    }

    #[test]
    fn a_quoted_line_break_in_an_error_stays_on_one_line() {
        // Found by fuzz/fuzz_targets/openfoam.rs: a string token was shown as written, and
        // its line breaks broke the error over several lines.
        let text = u("nonuniform List<vector> 1((1 0 \"a\nb\"));");
        let err = parse_vector_field("U", &text).unwrap_err().to_string();
        assert!(!err.contains('\n'), "{err}");
        assert!(err.ends_with(r#"found "a\nb""#), "{err}");
    }
}
