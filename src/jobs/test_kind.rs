//! A stand-in job kind whose behaviour the engine and worker tests choose through its
//! parameters.

use std::time::Duration;

use serde_json::{json, Value};

use super::{Artifact, JobKind, JobOutput, Prepared, RequestError, RunContext, SimError};
use crate::validate::Limits;

/// Panics when `params.panic` is true; otherwise writes one artifact named after `params.n`.
pub struct StandIn;

impl JobKind for StandIn {
    fn name(&self) -> &'static str {
        "stand-in"
    }
    fn summary(&self) -> &'static str {
        "test kind"
    }
    fn prepare(&self, params: Value, _: &Limits) -> Result<Prepared, RequestError> {
        Ok(Prepared { params, references: Default::default() })
    }
    fn estimate(&self, params: &Value, _: u64, _: &dyn crate::terrain::TerrainLookup) -> Result<super::Cost, SimError> {
        let mut cost = super::CostBuilder::new();
        cost.memory("memory", params["memory"].as_u64().unwrap_or(1 << 20));
        Ok(cost.work("steps", params["steps"].as_u64().unwrap_or(1) * 10).build("ms", 1000.0))
    }
    fn run(&self, params: &Value, _seed: u64, ctx: &RunContext) -> Result<JobOutput, SimError> {
        if params["panic"].as_bool() == Some(true) {
            panic!("a bug inside a simulation");
        }
        for step in 0..params["steps"].as_u64().unwrap_or(1) {
            ctx.check_cancelled()?;
            ctx.report("work", step, 10, "");
            std::thread::sleep(Duration::from_millis(10));
        }
        let bytes = params["n"].to_string().into_bytes();
        Ok(JobOutput {
            result: json!({ "n": params["n"] }),
            artifacts: vec![Artifact::new("n.txt", "text/plain", bytes)],
        })
    }
    fn draft(&self, params: &Value, _: &crate::validate::Limits) -> Result<Value, SimError> {
        Ok(params.clone())
    }
    fn draft_rule(&self) -> &'static str {
        "none"
    }
    fn sequence_steps(&self, _: &[u8]) -> Result<u64, SimError> {
        Ok(0)
    }
    fn replay(&self, p: &Value, _: &[u8], _: Option<u64>, ctx: &RunContext) -> Result<JobOutput, SimError> {
        self.run(p, 0, ctx)
    }
    fn request_schema(&self) -> super::kind::RequestSchema {
        ("StandIn".into(), utoipa::openapi::RefOr::T(utoipa::openapi::Schema::default()), Vec::new())
    }
}
