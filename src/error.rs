//! The library's error type.
//!
//! Owns: every failure a user can cause (bad input, unwritable output, a
//! scene the solver cannot handle). Invariant: each variant renders as one
//! line that names the offending file, mesh, primitive or setting, so that the
//! binary can print it after `error:` and exit with code 1.

use std::path::PathBuf;

/// Result alias used throughout the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Errors the library reports instead of panicking.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene file could not be read or parsed, or violates the contract.
    #[error("{path}: {message}")]
    Scene {
        /// The scene file.
        path: PathBuf,
        /// What is wrong, naming the mesh, primitive or node.
        message: String,
    },
    /// A scene without any light cannot be lit.
    #[error(
        "no light in the scene: looked for emissive materials (emissiveFactor, times \
         KHR_materials_emissive_strength, above 0), KHR_lights_punctual lights placed by \
         the scene's nodes, and a sky (--sky)"
    )]
    NoLight,
    /// The scene has nothing to solve (every triangle was dropped or absent).
    #[error("no usable triangles in the scene")]
    EmptyScene,
    /// An output file or folder could not be written.
    #[error("cannot write {path}: {message}")]
    Output {
        /// The file or folder.
        path: PathBuf,
        /// The cause.
        message: String,
    },
    /// An input file other than a scene (an image, a solution) is unreadable.
    #[error("cannot read {path}: {message}")]
    Input {
        /// The file.
        path: PathBuf,
        /// The cause.
        message: String,
    },
    /// An input file was read but its content cannot be used as asked
    /// (e.g. images of different sizes, a non-finite pixel).
    #[error("{path}: {message}")]
    Data {
        /// The file.
        path: PathBuf,
        /// What cannot be used.
        message: String,
    },
    /// Data could not be turned into the bytes of an output format (before
    /// any file is touched), e.g. a mesh whose arrays disagree in length.
    #[error("cannot encode {what}: {message}")]
    Encode {
        /// The output being encoded.
        what: &'static str,
        /// The cause.
        message: String,
    },
    /// The mesher could not triangulate a patch (names the patch).
    #[error("meshing failed: {0}")]
    Mesh(String),
    /// A setting is out of range or inconsistent.
    #[error("invalid setting: {0}")]
    Setting(String),
}

impl Error {
    /// A scene error for `path` with the given message.
    pub fn scene(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Scene {
            path: path.into(),
            message: message.into(),
        }
    }

    /// An output error for `path` from any displayable cause.
    pub fn output(path: impl Into<PathBuf>, cause: impl std::fmt::Display) -> Self {
        Error::Output {
            path: path.into(),
            message: cause.to_string(),
        }
    }

    /// An encoding error for the format `what` from any displayable cause.
    pub fn encode(what: &'static str, cause: impl std::fmt::Display) -> Self {
        Error::Encode {
            what,
            message: cause.to_string(),
        }
    }

    /// A data error for `path` from any displayable cause.
    pub fn data(path: impl Into<PathBuf>, cause: impl std::fmt::Display) -> Self {
        Error::Data {
            path: path.into(),
            message: cause.to_string(),
        }
    }

    /// An input error for `path` from any displayable cause.
    pub fn input(path: impl Into<PathBuf>, cause: impl std::fmt::Display) -> Self {
        Error::Input {
            path: path.into(),
            message: cause.to_string(),
        }
    }
}
