//! Error locations: TOML paths (`light[1].direction`) ⇄ byte spans ⇄ line:column, through
//! toml's spanned document tree, so that every [`SceneFileError::Invalid`] names the field
//! and where the file has it.

use super::SceneFileError;
use std::path::Path;
use toml::de::{DeTable, DeValue};

/// The parsed document with spans, for turning error spans into paths and paths into lines.
pub(super) struct Locator<'a> {
    text: &'a str,
    file: &'a Path,
    tree: Option<DeTable<'a>>,
}

#[derive(Debug, Clone, PartialEq)]
enum Seg {
    Key(String),
    Index(usize),
}

fn format_path(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

fn parse_path(path: &str) -> Vec<Seg> {
    let mut segs = Vec::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let mut pieces = part.split('[');
        if let Some(key) = pieces.next().filter(|k| !k.is_empty()) {
            segs.push(Seg::Key(key.to_string()));
        }
        for idx in pieces {
            if let Ok(i) = idx.trim_end_matches(']').parse() {
                segs.push(Seg::Index(i));
            }
        }
    }
    segs
}

fn contains(span: &std::ops::Range<usize>, pos: usize) -> bool {
    span.start <= pos && pos < span.end.max(span.start + 1)
}

/// Appends to `path` the deepest key or array element of `table` whose key or value span
/// contains `pos`; returns whether one was found.
fn find_in_table(table: &DeTable<'_>, pos: usize, path: &mut Vec<Seg>) -> bool {
    for (k, v) in table.iter() {
        path.push(Seg::Key(k.get_ref().to_string()));
        if find_in_value(v.get_ref(), pos, path)
            || contains(&k.span(), pos)
            || contains(&v.span(), pos)
        {
            return true;
        }
        path.pop();
    }
    false
}

fn find_in_value(value: &DeValue<'_>, pos: usize, path: &mut Vec<Seg>) -> bool {
    match value {
        DeValue::Table(t) => find_in_table(t, pos, path),
        DeValue::Array(a) => {
            for (i, item) in a.iter().enumerate() {
                path.push(Seg::Index(i));
                if find_in_value(item.get_ref(), pos, path) || contains(&item.span(), pos) {
                    return true;
                }
                path.pop();
            }
            false
        }
        _ => false,
    }
}

impl<'a> Locator<'a> {
    pub(super) fn new(text: &'a str, file: &'a Path) -> (Self, Vec<toml::de::Error>) {
        let (tree, errors) = DeTable::parse_recoverable(text);
        (
            Self {
                text,
                file,
                tree: Some(tree.into_inner()),
            },
            errors,
        )
    }

    fn line_col(&self, pos: usize) -> (usize, usize) {
        let pos = pos.min(self.text.len());
        let before = self.text.get(..pos).unwrap_or("");
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }

    fn span_of(&self, path: &str) -> Option<std::ops::Range<usize>> {
        let mut table = self.tree.as_ref()?;
        let mut value: Option<&toml::Spanned<DeValue<'_>>> = None;
        let mut span = None;
        for seg in parse_path(path) {
            match seg {
                Seg::Key(k) => {
                    let (key, v) = table.iter().find(|(key, _)| key.get_ref() == &k)?;
                    span = Some(if v.get_ref().is_table() || v.get_ref().is_array() {
                        key.span()
                    } else {
                        v.span()
                    });
                    value = Some(v);
                }
                Seg::Index(i) => {
                    let item = value?.get_ref().as_array()?.get(i)?;
                    span = Some(item.span());
                    value = Some(item);
                }
            }
            if let Some(t) = value.and_then(|v| v.get_ref().as_table()) {
                table = t;
            }
        }
        span
    }

    fn path_at(&self, pos: usize) -> String {
        let mut path = Vec::new();
        if let Some(tree) = &self.tree {
            find_in_table(tree, pos, &mut path);
        }
        format_path(&path)
    }

    /// An error about `field`, located at its span if the document has it.
    pub(super) fn err(&self, field: &str, problem: impl Into<String>) -> SceneFileError {
        let (line, column) = match self.span_of(field) {
            Some(s) => {
                let (l, c) = self.line_col(s.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        SceneFileError::Invalid {
            file: self.file.to_path_buf(),
            field: field.to_string(),
            line,
            column,
            problem: problem.into(),
        }
    }

    /// Whether the document has `path` (as a key, table or array element).
    pub(super) fn has(&self, path: &str) -> bool {
        self.span_of(path).is_some()
    }

    /// A TOML syntax error: about the text at its line:column, not about a field — the tree
    /// recovered around a broken line (an unclosed `[medium` header, say) puts the error's
    /// position inside whatever table follows, which is not where the problem is.
    pub(super) fn syntax_err(&self, e: &toml::de::Error) -> SceneFileError {
        let (line, column) = match e.span() {
            Some(s) => {
                let (l, c) = self.line_col(s.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        SceneFileError::Invalid {
            file: self.file.to_path_buf(),
            field: String::new(),
            line,
            column,
            problem: format!("TOML syntax error: {}", e.message().trim()),
        }
    }

    /// A toml error, located by its span (the field is the path at the span). A missing
    /// field of the top-level table comes with an empty span at the start of the document,
    /// where the first key is: that key is not the field at fault, so the error names none.
    pub(super) fn toml_err(&self, e: &toml::de::Error, fallback_field: &str) -> SceneFileError {
        match e.span() {
            Some(s) => {
                let (l, c) = self.line_col(s.start);
                let top_level_missing = s.is_empty() && e.message().starts_with("missing field");
                let field = if top_level_missing {
                    String::new()
                } else {
                    self.path_at(s.start)
                };
                SceneFileError::Invalid {
                    file: self.file.to_path_buf(),
                    field: if field.is_empty() {
                        fallback_field.to_string()
                    } else {
                        field
                    },
                    line: Some(l),
                    column: Some(c),
                    problem: e.message().trim().to_string(),
                }
            }
            None => self.err(fallback_field, e.message().trim()),
        }
    }
}
