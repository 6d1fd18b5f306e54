//! Evidence a reviewer can check offline.
//!
//! - [`build`]: `rig build`, the firmware and host programs built reproducibly, `build.json`;
//! - [`certify`]: `rig certify`, build → suite → evidence folder, and its [`certify::Verdict`];
//! - [`trace`]: the requirements file and the trace matrix;
//! - [`html`] (with [`svg`]): `report.html`, rendered from the saved records only;
//! - [`sbom`]: the CycloneDX SBOM; [`statement`]: in-toto statements (SLSA provenance, test result);
//! - [`manifest`]: the SHA-256 manifest, its ed25519 signature, and `rig verify`.
pub mod build;
pub mod certify;
pub mod html;
pub mod manifest;
pub mod sbom;
pub mod statement;
pub mod svg;
pub mod trace;
