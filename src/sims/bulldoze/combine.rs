//! Combination operators (paper §2.3): how an operation's shape meets the surface.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// How an operation combines with the surface. With z the current height, r the operation's
/// relief (its shape's height above its base) and v = base + r its absolute surface:
/// `add` z + r; `subtract` z − r; `max` max(z, v) (fill up to the shape); `min` min(z, v)
/// (cut down to the shape); `average` (z + v) / 2; `replace` v. Only samples inside the
/// operation's footprint change.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
#[schema(as = BulldozeOperator)]
pub enum Operator {
    Add,
    Subtract,
    Max,
    Min,
    Average,
    Replace,
}

impl Operator {
    /// The operator's name as it appears in requests.
    pub fn name(self) -> &'static str {
        match self {
            Operator::Add => "add",
            Operator::Subtract => "subtract",
            Operator::Max => "max",
            Operator::Min => "min",
            Operator::Average => "average",
            Operator::Replace => "replace",
        }
    }

    /// The new height of a sample at height `z` under an operation with `base` and `relief`.
    #[inline]
    pub fn combine(self, z: f64, base: f64, relief: f64) -> f64 {
        match self {
            Operator::Add => z + relief,
            Operator::Subtract => z - relief,
            Operator::Max => z.max(base + relief),
            Operator::Min => z.min(base + relief),
            Operator::Average => 0.5 * (z + base + relief),
            Operator::Replace => base + relief,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_operator_follows_its_rule() {
        let (z, base, relief) = (10.0, 4.0, 3.0);
        assert_eq!(Operator::Add.combine(z, base, relief), 13.0);
        assert_eq!(Operator::Subtract.combine(z, base, relief), 7.0);
        assert_eq!(Operator::Max.combine(z, base, relief), 10.0);
        assert_eq!(Operator::Min.combine(z, base, relief), 7.0);
        assert_eq!(Operator::Average.combine(z, base, relief), 8.5);
        assert_eq!(Operator::Replace.combine(z, base, relief), 7.0);
    }

    #[test]
    fn operators_are_snake_case_in_json() {
        for op in
            [Operator::Add, Operator::Subtract, Operator::Max, Operator::Min, Operator::Average, Operator::Replace]
        {
            assert_eq!(serde_json::to_value(op).unwrap(), op.name());
        }
        assert_eq!(serde_json::from_str::<Operator>("\"average\"").unwrap(), Operator::Average);
    }
}
