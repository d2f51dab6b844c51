//! What is wrong inside a file being decoded (a mesh, an HDRI), before the
//! error that names the file wraps it.

/// A problem in a file's content: a line, an element, a header field.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct ContentError(pub String);

impl From<String> for ContentError {
    fn from(message: String) -> Self {
        Self(message)
    }
}

impl From<&str> for ContentError {
    fn from(message: &str) -> Self {
        Self(message.to_string())
    }
}
