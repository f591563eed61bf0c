//! # quadtex-eval
//!
//! The evidence behind quadtex's claims, kept apart from the renderer: the
//! contenders a comparison runs ([`contenders`]), error metrics against a
//! reference ([`metrics`]), the closed-form reference of a textured plane
//! ([`reference`](mod@reference)), pictures ([`montage`]), the report ([`report`]) and the
//! lookup records handed to peer libraries ([`peers`]). No file I/O here;
//! the CLI writes what these build.
#![forbid(unsafe_code)]

pub mod contenders;
pub mod metrics;
pub mod montage;
pub mod peers;
pub mod reference;
pub mod report;
