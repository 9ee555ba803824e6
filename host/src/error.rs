//! The library's error: a kind a caller can match on (no GPU, too large for the device, a scene
//! file's mistake with its file and line, I/O, device lost, …) and the one-line message the
//! command line prints.
//!
//! ```
//! use kdray::{Error, Gpu};
//! match Gpu::new() {
//!     Ok(gpu) => println!("tracing on {}", gpu.adapter_line()),
//!     Err(Error::NoAdapter(why)) => println!("no GPU ({why}): tracing on the CPU"),
//!     Err(e) => println!("the GPU failed: {e}"),
//! }
//! ```
use std::fmt;
use std::path::PathBuf;

/// Everything the library can fail with. Errors with context (`Context`) keep the original
/// kind underneath: [`Error::kind`] finds it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No usable Vulkan adapter, or not the one asked for.
    #[error("{0}")]
    NoAdapter(String),
    /// The scene or a buffer exceeds what the device (binding and buffer limits) or a data
    /// format (node and index widths) can hold.
    #[error("{0}")]
    TooLarge(String),
    /// A scene file (OBJ, MTL, TOML) that cannot be read as a scene: the file, the line when
    /// one is to blame, and what is wrong.
    #[error("{file}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    SceneFile {
        /// The file as given.
        file: String,
        /// The line (1-based), when one line is to blame.
        line: Option<usize>,
        /// What is wrong with it.
        message: String,
    },
    /// A scene that is not valid whatever its source: empty, non-finite vertices, a camera
    /// that sees nothing, lights without power, an unknown built-in name.
    #[error("{0}")]
    Scene(String),
    /// Reading or writing a file.
    #[error("{}{error}", if path.as_os_str().is_empty() { String::new() } else { format!("{}: ", path.display()) })]
    Io {
        /// The file (empty when not known).
        path: PathBuf,
        /// What the system said.
        error: std::io::Error,
    },
    /// The GPU did not finish a submission or a read-back within the time limit (a hang or a
    /// lost device); what was recorded before is not affected.
    #[error("GPU device lost: {0}")]
    DeviceLost(String),
    /// An argument the call cannot take: an option out of range, a combination that does not
    /// exist, rays that are not finite.
    #[error("{0}")]
    InvalidInput(String),
    /// A device or shader failure: a kernel that does not compile on this driver, a host pass
    /// that does not match its kernel's bindings, a failed mapping.
    #[error("{0}")]
    Gpu(String),
    /// What was being done when `inner` happened. The message holds the whole chain on one
    /// line (`context: inner`), so [`std::error::Error::source`] is `None` and a reporter that
    /// walks sources (anyhow's `{:#}`) prints nothing twice; [`Error::kind`] finds the kind.
    #[error("{context}: {inner}")]
    Context {
        /// What was being done.
        context: String,
        /// What went wrong.
        inner: Box<Error>,
    },
}

impl Error {
    /// The error under any context added on the way up.
    pub fn kind(&self) -> &Error {
        match self {
            Error::Context { inner, .. } => inner.kind(),
            e => e,
        }
    }

    /// This error with `context` in front (`context: error`).
    pub fn context(self, context: impl fmt::Display) -> Error {
        Error::Context { context: context.to_string(), inner: Box::new(self) }
    }

    /// An I/O error about `path`.
    pub fn io(path: impl Into<PathBuf>, error: std::io::Error) -> Error {
        Error::Io { path: path.into(), error }
    }
}

impl From<std::io::Error> for Error {
    fn from(error: std::io::Error) -> Error {
        Error::Io { path: PathBuf::new(), error }
    }
}

impl From<fmt::Error> for Error {
    fn from(_: fmt::Error) -> Error {
        Error::Io { path: PathBuf::new(), error: std::io::Error::other("formatting failed") }
    }
}

impl From<image::ImageError> for Error {
    fn from(e: image::ImageError) -> Error {
        match e {
            image::ImageError::IoError(error) => Error::Io { path: PathBuf::new(), error },
            e => Error::InvalidInput(e.to_string()),
        }
    }
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Context for fallible results, as `anyhow::Context` gives (`.context("reading x")?`).
pub trait Context<T> {
    /// Puts `context` in front of the error.
    fn context<C: fmt::Display>(self, context: C) -> Result<T>;
    /// Puts the context `f` makes in front of the error (made only on failure).
    fn with_context<C: fmt::Display, F: FnOnce() -> C>(self, f: F) -> Result<T>;
}

impl<T, E: Into<Error>> Context<T> for std::result::Result<T, E> {
    fn context<C: fmt::Display>(self, context: C) -> Result<T> {
        self.map_err(|e| e.into().context(context))
    }
    fn with_context<C: fmt::Display, F: FnOnce() -> C>(self, f: F) -> Result<T> {
        self.map_err(|e| e.into().context(f()))
    }
}

/// `err!(Kind: "format", args…)`: an [`Error`] of a message kind;
/// `err!(SceneFile(file, line): "format", …)` for a scene file's mistake.
macro_rules! err {
    (SceneFile($file:expr, $line:expr): $($arg:tt)+) => {
        $crate::Error::SceneFile { file: ($file).to_string(), line: $line, message: format!($($arg)+) }
    };
    ($kind:ident: $($arg:tt)+) => {
        $crate::Error::$kind(format!($($arg)+))
    };
}

/// `bail!(…)`: returns `Err(err!(…))`.
macro_rules! bail {
    ($($arg:tt)+) => {
        return Err($crate::error::err!($($arg)+))
    };
}

/// `ensure!(condition, …)`: `bail!(…)` unless the condition holds.
macro_rules! ensure {
    ($cond:expr, $($arg:tt)+) => {
        if !$cond {
            $crate::error::bail!($($arg)+);
        }
    };
}

pub(crate) use {bail, ensure, err};

#[cfg(test)]
mod tests {
    use super::*;

    /// What a reporter that walks `source()` prints (as the CLI does): the message, then
    /// `: source` for every source.
    fn source_chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut cur = e.source();
        while let Some(c) = cur {
            s += &format!(": {c}");
            cur = c.source();
        }
        s
    }

    #[test]
    fn kinds_survive_context_and_messages_read_as_one_line() {
        let e = err!(SceneFile("box.obj", Some(12)): "face {} has {} vertices", 3, 2).context("loading the scene");
        assert_eq!(e.to_string(), "loading the scene: box.obj:12: face 3 has 2 vertices");
        assert!(matches!(e.kind(), Error::SceneFile { line: Some(12), .. }));
        let io: Result<()> = Err(std::io::Error::new(std::io::ErrorKind::NotFound, "gone")).with_context(|| "reading x.toml");
        let e = io.unwrap_err();
        assert_eq!(e.to_string(), "reading x.toml: gone");
        assert!(matches!(e.kind(), Error::Io { .. }));
        assert_eq!(Error::io("a.png", std::io::Error::other("full")).to_string(), "a.png: full");
        // One line, nothing repeated by a reporter that walks `source()` (the CLI's anyhow).
        assert!(std::error::Error::source(&e).is_none());
        assert_eq!(source_chain(&e), "reading x.toml: gone");
    }
}
