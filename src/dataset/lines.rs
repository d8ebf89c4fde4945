//! The one line reader of the text formats (TUM lists and trajectories,
//! ICL-NUIM associations, 7-Scenes pose matrices), and the one way their
//! errors name the file and line.

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
