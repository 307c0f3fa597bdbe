//! The recorded operation sequence: every primitive and every move with its path heights
//! resolved, so a replay rebuilds the result without looking anything up again.

use serde::{Deserialize, Serialize};

use super::params::{PrimitiveOp, Window};
use super::path::MoveStep;
use super::refine::Refine;
use super::scopes::{GlobalOp, LocalOp};
use crate::jobs::Sequence;
use crate::terrain::TerrainSource;

/// `sequence.json` of a bulldoze job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BulldozeSequence {
    /// The starting terrain, as requested.
    pub terrain: TerrainSource,
    /// Metres between samples of the grid the steps start on (a `refine` step resamples it).
    pub resolution_m: f32,
    pub window: Option<Window>,
    /// One step per primitive and per move, in the order applied.
    pub steps: Vec<Step>,
}

/// One recorded step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Step {
    Primitive(PrimitiveOp),
    Move(MoveStep),
    Local(LocalOp),
    Global(GlobalOp),
    Refine(Refine),
}

impl Sequence for BulldozeSequence {
    fn steps(&self) -> u64 {
        self.steps.len() as u64
    }
}

/// Consecutive steps that are applied together: a primitive, or the moves of one pass.
pub enum Group<'a> {
    Primitive(&'a PrimitiveOp),
    Pass(Vec<MoveStep>),
    Local(&'a LocalOp),
    Global(&'a GlobalOp),
    Refine(&'a Refine),
}

/// Split steps into primitives and passes (runs of moves with the same pass number).
pub fn groups(steps: &[Step]) -> Vec<Group<'_>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < steps.len() {
        match &steps[i] {
            Step::Primitive(p) => {
                out.push(Group::Primitive(p));
                i += 1;
            }
            Step::Local(l) => {
                out.push(Group::Local(l));
                i += 1;
            }
            Step::Global(g) => {
                out.push(Group::Global(g));
                i += 1;
            }
            Step::Refine(r) => {
                out.push(Group::Refine(r));
                i += 1;
            }
            Step::Move(first) => {
                let mut moves = Vec::new();
                while let Some(Step::Move(m)) = steps.get(i) {
                    if m.pass != first.pass {
                        break;
                    }
                    moves.push(m.clone());
                    i += 1;
                }
                out.push(Group::Pass(moves));
            }
        }
    }
    out
}
