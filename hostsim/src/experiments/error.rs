//! Why an experiment could not run: one error for bench, paper, the fit and the scale sweep,
//! which fail for the same reasons. Each says what was asked or which file it concerns.

use crate::fabric::RunError;
use crate::input::scene::SceneError;
use crate::run::balance::BalanceError;
use crate::run::render::RenderError;
use std::path::PathBuf;

use super::sod::SOD_FILE;

/// Why an experiment could not run.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// A scene of the experiment did not load.
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// A render failed.
    #[error("{0}")]
    Render(#[from] RenderError),
    /// A simulated run failed.
    #[error("{0}")]
    Run(#[from] RunError),
    /// The paper's static load balancing failed.
    #[error("{0}")]
    Balance(#[from] BalanceError),
    /// SOD is not where the command was told to read it.
    #[error("{}: SOD not found: expected {SOD_FILE}, or a folder holding it (--substitute renders the built-in molecule instead)", .0.display())]
    NoSod(PathBuf),
    /// What was asked cannot be measured (a machine shape, a view on a volume).
    #[error("{0}")]
    Asked(String),
    /// A measurement the experiment needs did not come out (a time, a fit, a profile).
    #[error("{0}")]
    Missing(String),
    /// An output (a table, an image, a plot) could not be written.
    #[error("{}: {message}", .path.display())]
    Output {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        message: String,
    },
}
