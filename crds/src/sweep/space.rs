//! The parameter space: each parameter's values, and the cells (every combination, the
//! last parameter varying fastest).

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::{Parameter, SimulationSweepSpec};
use crate::random::{Purpose, Rng};
use crate::validate::FieldError;

/// Most values one parameter may take.
pub const MAX_VALUES: usize = 1000;

/// One combination of parameter values.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(rename_all = "camelCase")]
pub struct Cell {
    /// Position in the grid, from 0.
    pub index: u32,
    /// `(parameter name, value)` in the order of `spec.parameters`.
    pub values: Vec<(String, Value)>,
}

impl Cell {
    /// `wind=10, seed=3`: how reports and statuses name the cell.
    pub fn label(&self) -> String {
        self.values.iter().map(|(name, v)| format!("{name}={}", show(v))).collect::<Vec<_>>().join(", ")
    }

    /// The value of parameter `name`.
    pub fn value(&self, name: &str) -> Option<&Value> {
        self.values.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }
}

/// A value as a label shows it: strings without quotes, everything else as JSON.
pub fn show(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// The values of parameter `i` (`spec.parameters[i]`), drawn with the sweep's `seed` for
/// `random`.
///
/// # Errors
/// Every problem with the parameter's values, with its field path.
pub fn values_of(p: &Parameter, i: usize, seed: u64) -> Result<Vec<Value>, Vec<FieldError>> {
    let at = |field: &str, message: String| FieldError { path: format!("spec.parameters[{i}].{field}"), message };
    let given = [p.values.is_some(), p.range.is_some(), p.random.is_some()].iter().filter(|g| **g).count();
    if given != 1 {
        return Err(vec![at("values", format!("give exactly one of values, range and random; got {given}"))]);
    }
    let number = |x: f64| serde_json::Number::from_f64(x).map(Value::Number);
    let values: Vec<Value> = if let Some(values) = &p.values {
        values.clone()
    } else if let Some(r) = p.range {
        if !(r.from.is_finite() && r.to.is_finite() && r.step.is_finite()) || r.step <= 0.0 || r.to < r.from {
            return Err(vec![at(
                "range",
                format!("needs finite from <= to and step > 0, got from {} to {} step {}", r.from, r.to, r.step),
            )]);
        }
        let n = ((r.to - r.from) / r.step + 1e-9).floor() as usize + 1;
        if n > MAX_VALUES {
            return Err(vec![at("range", format!("gives {n} values, over the limit of {MAX_VALUES}"))]);
        }
        // Whole numbers stay integers (`count: 3`, not `3.0`), so integer fields take them.
        (0..n).map(|k| r.from + k as f64 * r.step).map(|x| integral(x).or_else(|| number(x)).expect("finite")).collect()
    } else {
        let r = p.random.expect("one of the three is given");
        if !(r.min.is_finite() && r.max.is_finite()) || r.max <= r.min {
            return Err(vec![at("random", format!("needs finite min < max, got min {} max {}", r.min, r.max))]);
        }
        if r.count == 0 || r.count as usize > MAX_VALUES {
            return Err(vec![at("random.count", format!("must be between 1 and {MAX_VALUES}, got {}", r.count))]);
        }
        // One stream per parameter: adding a parameter does not change another's draws.
        let mut rng = Rng::stream(seed, i as u64, Purpose::Sweep);
        (0..r.count)
            .map(|_| rng.uniform(r.min, r.max))
            .map(|x| if r.integer == Some(true) { Value::from(x.floor() as i64) } else { number(x).expect("finite") })
            .collect()
    };
    if values.is_empty() {
        return Err(vec![at("values", "is empty: a parameter needs at least one value".into())]);
    }
    if values.len() > MAX_VALUES {
        return Err(vec![at("values", format!("has {} values, over the limit of {MAX_VALUES}", values.len()))]);
    }
    Ok(values)
}

fn integral(x: f64) -> Option<Value> {
    (x.fract() == 0.0 && x.abs() < 9.0e15).then(|| Value::from(x as i64))
}

/// Every cell of the grid, given each parameter's values.
pub fn cells(spec: &SimulationSweepSpec, values: &[Vec<Value>]) -> Vec<Cell> {
    let total: usize = values.iter().map(Vec::len).product();
    (0..total)
        .map(|index| {
            let mut rest = index;
            let mut picked = vec![Value::Null; values.len()];
            for (k, vals) in values.iter().enumerate().rev() {
                picked[k] = vals[rest % vals.len()].clone();
                rest /= vals.len();
            }
            let values = spec.parameters.iter().map(|p| p.name.clone()).zip(picked).collect();
            Cell { index: index as u32, values }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::{NumberRange, RandomSample};
    use serde_json::json;

    fn param(values: Option<Vec<Value>>, range: Option<NumberRange>, random: Option<RandomSample>) -> Parameter {
        Parameter { name: "p".into(), field: "spec.seed".into(), values, range, random }
    }

    #[test]
    fn ranges_are_inclusive_and_keep_whole_numbers_integers() {
        let p = param(None, Some(NumberRange { from: 0.0, to: 10.0, step: 2.5 }), None);
        assert_eq!(values_of(&p, 0, 0).unwrap(), [json!(0), json!(2.5), json!(5), json!(7.5), json!(10)]);
        let p = param(None, Some(NumberRange { from: 0.0, to: 1.0, step: 0.1 }), None);
        assert_eq!(values_of(&p, 0, 0).unwrap().len(), 11, "rounding does not drop the end point");
    }

    #[test]
    fn random_samples_depend_on_the_seed_and_stay_in_bounds() {
        let p = param(None, None, Some(RandomSample { min: 2.0, max: 4.0, count: 50, integer: None }));
        let a = values_of(&p, 0, 7).unwrap();
        assert_eq!(a, values_of(&p, 0, 7).unwrap());
        assert_ne!(a, values_of(&p, 0, 8).unwrap());
        assert_ne!(a, values_of(&p, 1, 7).unwrap(), "each parameter has its own stream");
        assert!(a.iter().all(|v| (2.0..4.0).contains(&v.as_f64().unwrap())));
        let p = param(None, None, Some(RandomSample { min: 0.0, max: 100.0, count: 20, integer: Some(true) }));
        assert!(values_of(&p, 0, 1).unwrap().iter().all(|v| v.is_i64()));
    }

    #[test]
    fn bad_values_name_the_parameter() {
        let e = values_of(&param(Some(vec![]), None, None), 2, 0).unwrap_err();
        assert_eq!(e[0].path, "spec.parameters[2].values");
        assert!(e[0].message.contains("is empty"));
        let e =
            values_of(&param(Some(vec![json!(1)]), Some(NumberRange { from: 0.0, to: 1.0, step: 1.0 }), None), 0, 0)
                .unwrap_err();
        assert!(e[0].message.contains("exactly one of values, range and random; got 2"), "{e:?}");
        let e = values_of(&param(None, Some(NumberRange { from: 5.0, to: 1.0, step: 1.0 }), None), 0, 0).unwrap_err();
        assert_eq!(e[0].path, "spec.parameters[0].range");
    }
}
