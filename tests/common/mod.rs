#![allow(dead_code)]

pub mod bodies;
pub mod cli;
pub mod glb_topology;
pub mod gltf_validator;
pub mod processes;
pub mod server;
pub mod sse;
