//! A TOML error located in the text it came from: the line number and the line, so that a
//! message reads "line 6 `foo_mm = 1`: unknown field `foo_mm`, expected ...".

use thiserror::Error;

/// A TOML syntax or deserialisation error, with the line it points at when known.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("{}", self.render())]
pub struct TomlError {
    /// The 1-based line number and the line's text (trimmed), when the error has a span.
    pub line: Option<(usize, String)>,
    /// The parser's message.
    pub message: String,
}

impl TomlError {
    /// The error `e` of parsing `text`, located in it.
    pub fn located(text: &str, e: &toml::de::Error) -> Self {
        TomlError {
            line: e.span().map(|span| {
                let (number, line) = line_at(text, span.start);
                (number, line.to_string())
            }),
            message: e.message().trim().to_string(),
        }
    }

    fn render(&self) -> String {
        match &self.line {
            Some((number, line)) => format!("line {number} `{line}`: {}", self.message),
            None => self.message.clone(),
        }
    }
}

/// Where a byte offset lies in `text`: its 1-based line number and the line's text.
fn line_at(text: &str, offset: usize) -> (usize, &str) {
    let start = text
        .get(..offset)
        .and_then(|b| b.rfind('\n'))
        .map_or(0, |i| i + 1);
    let number = text.get(..start).map_or(0, |b| b.matches('\n').count()) + 1;
    let line = text
        .get(start..)
        .and_then(|rest| rest.lines().next())
        .unwrap_or("");
    (number, line.trim())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn an_error_names_its_line() {
        let text = "a = 1\nb = \"x\n";
        let e = text.parse::<toml::Table>().unwrap_err();
        let located = TomlError::located(text, &e);
        assert_eq!(located.line.as_ref().map(|l| l.0), Some(2));
        assert!(
            located.to_string().starts_with("line 2 `b = \"x`: "),
            "{located}"
        );
    }
}
