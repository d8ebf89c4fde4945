//! The one line reader of the text formats (TUM lists and trajectories,
//! ICL-NUIM associations, 7-Scenes pose matrices, Stray Scanner's CSVs),
//! the one way their errors name the file and line, and the one rule for a
//! recording cut short ([`parse_rows`]): a malformed last row is a row the
//! recorder was writing when it stopped, skipped with a warning.

use super::DatasetError;

/// A line of a text file with content: trimmed, with its 1-based number.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line<'a> {
    file: &'a str,
    /// 1-based line number (0 when there was no line).
    pub number: usize,
    /// The line, trimmed.
    pub text: &'a str,
}

impl<'a> Line<'a> {
    /// A stand-in for "no line" of `file` (line 0, empty), for errors about
    /// a file as a whole.
    pub fn none(file: &'a str) -> Self {
        Self {
            file,
            number: 0,
            text: "",
        }
    }

    /// The error saying what is wrong with this line.
    pub fn malformed(&self, reason: &str) -> DatasetError {
        DatasetError::MalformedLine {
            file: self.file.to_owned(),
            line_number: self.number,
            line: self.text.to_owned(),
            reason: reason.to_owned(),
        }
    }

    /// The whitespace-separated tokens of the line.
    pub fn tokens(&self) -> std::str::SplitWhitespace<'a> {
        self.text.split_whitespace()
    }
}

/// The lines of `text` (file `file`) that have content, trimmed: blank
/// lines skipped, and `#` comment lines too when `comments` is set.
pub(crate) fn content_lines<'a>(
    text: &'a str,
    file: &'a str,
    comments: bool,
) -> impl Iterator<Item = Line<'a>> {
    text.lines().enumerate().filter_map(move |(i, raw)| {
        let text = raw.trim();
        let skip = text.is_empty() || (comments && text.starts_with('#'));
        (!skip).then_some(Line {
            file,
            number: i + 1,
            text,
        })
    })
}

/// Parses the content lines of `text` (file `file`) with `parse` (given the
/// line's position among the content lines; `Ok(None)` skips a line, a
/// header), in file order.
///
/// A [`DatasetError::MalformedLine`] on the last content line, after at
/// least one line before it, is a row cut off by a recording that stopped
/// mid-write (an app killed while writing `odometry.csv`): it is skipped
/// and pushed onto `warnings` as [`DatasetError::CutOffLine`], so that the
/// recording plays what it has. A malformed line anywhere else, or a file
/// whose only line is malformed, is an error: that file is not a cut-short
/// recording but a wrong one.
pub(crate) fn parse_rows<'a, T>(
    text: &'a str,
    file: &'a str,
    comments: bool,
    warnings: &mut Vec<DatasetError>,
    mut parse: impl FnMut(usize, Line<'a>) -> Result<Option<T>, DatasetError>,
) -> Result<Vec<T>, DatasetError> {
    let mut out = Vec::new();
    let mut lines = content_lines(text, file, comments).enumerate().peekable();
    while let Some((i, line)) = lines.next() {
        match parse(i, line) {
            Ok(Some(row)) => out.push(row),
            Ok(None) => {}
            Err(DatasetError::MalformedLine {
                file,
                line_number,
                line,
                reason,
            }) if i > 0 && lines.peek().is_none() => {
                warnings.push(DatasetError::CutOffLine {
                    file,
                    line_number,
                    line,
                    reason,
                });
            }
            Err(e) => return Err(e),
        }
    }
    Ok(out)
}

/// [`parse_rows`] where a cut-off last row is an error too: for files given
/// as they are meant to be (an estimate to evaluate), not a recording.
pub(crate) fn parse_rows_strict<'a, T>(
    text: &'a str,
    file: &'a str,
    comments: bool,
    parse: impl FnMut(usize, Line<'a>) -> Result<Option<T>, DatasetError>,
) -> Result<Vec<T>, DatasetError> {
    let mut warnings = Vec::new();
    let rows = parse_rows(text, file, comments, &mut warnings, parse)?;
    strictly(rows, warnings.pop())
}

/// `value`, or the error a strict reader makes of `warning`: a cut-off
/// last row ([`DatasetError::CutOffLine`]) is a malformed line there.
pub(crate) fn strictly<T>(value: T, warning: Option<DatasetError>) -> Result<T, DatasetError> {
    match warning {
        Some(DatasetError::CutOffLine {
            file,
            line_number,
            line,
            reason,
        }) => Err(DatasetError::MalformedLine {
            file,
            line_number,
            line,
            reason,
        }),
        Some(other) => Err(other),
        None => Ok(value),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numbers(text: &str, warnings: &mut Vec<DatasetError>) -> Result<Vec<f64>, DatasetError> {
        parse_rows(text, "n.csv", true, warnings, |i, line| {
            if i == 0 && line.text == "value" {
                return Ok(None);
            }
            line.text
                .parse::<f64>()
                .map(Some)
                .map_err(|_| line.malformed("not a number"))
        })
    }

    #[test]
    fn a_cut_off_last_row_is_one_warning_naming_file_and_line() {
        let mut warnings = Vec::new();
        let rows = numbers("value\n1.5\n\n2.5\n3.", &mut warnings).expect("reads");
        assert_eq!(rows, vec![1.5, 2.5, 3.0]);
        assert!(warnings.is_empty());
        let rows = numbers("value\n1.5\n2.5\n3.2, 4", &mut warnings).expect("reads");
        assert_eq!(rows, vec![1.5, 2.5]);
        assert_eq!(warnings.len(), 1);
        let text = warnings[0].to_string();
        assert!(
            text.starts_with("n.csv, line 4: ") && text.contains("`3.2, 4`"),
            "{text}"
        );
    }

    #[test]
    fn a_malformed_row_elsewhere_or_alone_is_an_error() {
        let mut warnings = Vec::new();
        for (text, line_number) in [("1\nx\n2\n", 2), ("x\n", 1), ("# c\n\nx", 3)] {
            let err = numbers(text, &mut warnings).expect_err(text);
            assert!(
                matches!(err, DatasetError::MalformedLine { line_number: n, .. } if n == line_number),
                "{text}: {err:?}"
            );
        }
        assert!(warnings.is_empty());
        let strict = parse_rows_strict("1\n2\nx", "s.txt", true, |_, line| {
            line.text
                .parse::<f64>()
                .map(Some)
                .map_err(|_| line.malformed("not a number"))
        });
        assert!(matches!(
            strict,
            Err(DatasetError::MalformedLine { line_number: 3, .. })
        ));
    }
}
