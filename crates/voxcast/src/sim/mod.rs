//! Simulators that produce volumes: cloud particle systems.

pub mod cloud;
