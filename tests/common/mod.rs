//! Shared statistical test harness for the integration tests.
//!
//! Each integration test binary compiles this module separately (`mod common;`)
//! and typically uses only part of it, hence the crate-level `dead_code`
//! allowance below.
//!
//! * [`chi2`]: Pearson χ² goodness-of-fit of a direction sampler against the
//!   density it claims, over the whole sphere, in the manner of the `chi2`
//!   tests of pbrt-v4 and Mitsuba 3.
//! * [`ks`]: one-sample Kolmogorov–Smirnov test of scalar samples against a
//!   known CDF.
//! * [`rng`]: deterministic test randomness (xorshift64*).
//! * [`scenes`]: cameras the render tests share.
//! * [`maps`]: environment map files the tests write.
#![allow(dead_code)]

pub mod chi2;
pub mod cli;
pub mod ks;
pub mod maps;
pub mod rng;
pub mod scenes;
