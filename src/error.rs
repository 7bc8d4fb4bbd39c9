//! One error type for the library: every variant names the file (or the argument) and the problem,
//! so the CLI can print it as is and exit non-zero.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file exists but its content is not what its format says (truncated, corrupt, inconsistent).
    #[error("{}: {msg}", path.display())]
    Format { path: PathBuf, msg: String },
    #[error("{}: cannot decode image: {source}", path.display())]
    Image {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error("{}: invalid JSON: {source}", path.display())]
    Json {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    /// A bad argument or a request that cannot be met (no file involved).
    #[error("{0}")]
    Invalid(String),
    /// An external program or library is missing or failed; `hint` says how to fix it.
    #[error("{what}: {msg}")]
    External { what: String, msg: String },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }
    pub fn format(path: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Error::Format {
            path: path.as_ref().to_path_buf(),
            msg: msg.into(),
        }
    }
    pub fn image(path: impl AsRef<Path>, source: image::ImageError) -> Self {
        Error::Image {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }
    pub fn json(path: impl AsRef<Path>, source: serde_json::Error) -> Self {
        Error::Json {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(msg.into())
    }
    pub fn external(what: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::External {
            what: what.into(),
            msg: msg.into(),
        }
    }
}
