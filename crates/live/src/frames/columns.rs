//! A frame's JSON line into its `seq` and its columns in [`FRAME_CHANNELS`]' order. Straight
//! into the columns by serde, the way a good frame takes (no `serde_json::Value` built and
//! copied: that was more than half the cost of a frame); a frame that way does not take is
//! read again through a `Value`, which says exactly what is wrong — or takes what only it
//! takes (a key given twice: the last counts), so both ways take the same frames.

use super::FRAME_CHANNELS;
use serde::{Deserialize, Deserializer};
use serde_json::Value;

/// A frame's `seq` (when given) and its columns in [`FRAME_CHANNELS`]' order, each as long as
/// `t` and finite.
pub(super) type Columns = (Option<u64>, Vec<Vec<f64>>);

/// A frame as serde reads it into columns: [`FRAME_CHANNELS`], in that order (a test holds
/// them to it), and `seq`; other keys are ignored.
#[derive(Deserialize)]
struct Typed {
    #[serde(default)]
    seq: Seq,
    t: Vec<f64>,
    theta_dy: Vec<f64>,
    theta_en: Vec<f64>,
    omega_dy: Vec<f64>,
    omega_en: Vec<f64>,
    torque_shaft: Vec<f64>,
}

/// `seq` when the key is there: a whole number ≥ 0 (`null` is not one).
#[derive(Default)]
struct Seq(Option<u64>);

impl<'de> Deserialize<'de> for Seq {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        u64::deserialize(d).map(|s| Self(Some(s)))
    }
}

/// The frame `line`'s `seq` and columns, or what is wrong with it.
pub(super) fn columns(line: &str) -> Result<Columns, String> {
    if let Ok(f) = serde_json::from_str::<Typed>(line) {
        let cols = vec![
            f.t,
            f.theta_dy,
            f.theta_en,
            f.omega_dy,
            f.omega_en,
            f.torque_shaft,
        ];
        let n = cols[0].len();
        if cols
            .iter()
            .all(|c| c.len() == n && c.iter().all(|x| x.is_finite()))
        {
            return Ok((f.seq.0, cols));
        }
    }
    through_value(line)
}

/// [`columns`] through a `serde_json::Value`: every check, each with its message.
fn through_value(line: &str) -> Result<Columns, String> {
    let v: Value = serde_json::from_str(line).map_err(|e| format!("not a JSON object: {e}"))?;
    let obj = v.as_object().ok_or("not a JSON object")?;
    let seq = match obj.get("seq") {
        None => None,
        Some(s) => Some(
            s.as_u64()
                .ok_or_else(|| format!("seq {s}: expected a whole number ≥ 0"))?,
        ),
    };
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(FRAME_CHANNELS.len());
    for name in FRAME_CHANNELS {
        let col = obj
            .get(name)
            .and_then(Value::as_array)
            .ok_or_else(|| format!("channel '{name}' missing or not an array"))?;
        if let Some(t) = cols.first().filter(|t| t.len() != col.len()) {
            return Err(format!(
                "channel '{name}' has {} values, 't' has {}",
                col.len(),
                t.len()
            ));
        }
        let mut values = Vec::with_capacity(col.len());
        for (i, x) in col.iter().enumerate() {
            match x.as_f64() {
                Some(f) if f.is_finite() => values.push(f),
                _ => {
                    return Err(format!(
                        "'{name}' value {i} is {x}: expected a finite number"
                    ))
                }
            }
        }
        cols.push(values);
    }
    Ok((seq, cols))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// [`Typed`]'s fields are [`FRAME_CHANNELS`], in order.
    #[test]
    fn the_typed_frame_holds_the_frame_channels_in_order() {
        assert_eq!(
            FRAME_CHANNELS,
            [
                "t",
                "theta_dy",
                "theta_en",
                "omega_dy",
                "omega_en",
                "torque_shaft"
            ]
        );
        let line = r#"{"t":[0],"theta_dy":[1],"theta_en":[2],"omega_dy":[3],"omega_en":[4],"torque_shaft":[5],"x":"y"}"#;
        let (seq, cols) = columns(line).unwrap();
        assert_eq!(seq, None);
        assert_eq!(cols, (0..6).map(|k| vec![f64::from(k)]).collect::<Vec<_>>());
    }

    /// Both ways take the same frames, with the same result; where serde's way does not take
    /// one, the other says what is wrong.
    #[test]
    fn both_ways_agree() {
        let ok = [
            r#"{"seq":3,"t":[0,1e-4],"theta_dy":[0,0.5],"theta_en":[0,0.25],"omega_dy":[1,2],"omega_en":[3,4],"torque_shaft":[-1.5,2]}"#,
            // A key twice: the last counts, both ways.
            r#"{"t":[9],"t":[0],"theta_dy":[1],"theta_en":[2],"omega_dy":[3],"omega_en":[4],"torque_shaft":[5]}"#,
        ];
        for line in ok {
            assert_eq!(
                columns(line).unwrap(),
                through_value(line).unwrap(),
                "{line}"
            );
        }
        assert_eq!(columns(ok[1]).unwrap().1[0], [0.0]);
        let all =
            r#""theta_dy":[1],"theta_en":[2],"omega_dy":[3],"omega_en":[4],"torque_shaft":[5]"#;
        for (line, says) in [
            (
                format!(r#"{{"seq":null,"t":[0],{all}}}"#),
                "seq null: expected a whole number",
            ),
            (format!(r#"{{"seq":-1,"t":[0],{all}}}"#), "seq -1: expected"),
            (
                format!(r#"{{"seq":1.5,"t":[0],{all}}}"#),
                "seq 1.5: expected",
            ),
            (
                format!(r#"{{"t":[null],{all}}}"#),
                "'t' value 0 is null: expected a finite number",
            ),
            (
                format!(r#"{{"t":["NaN"],{all}}}"#),
                "'t' value 0 is \"NaN\"",
            ),
            (
                format!(r#"{{"t":[0,1],{all}}}"#),
                "channel 'theta_dy' has 1 values, 't' has 2",
            ),
            (
                format!(r#"{{"t":0,{all}}}"#),
                "channel 't' missing or not an array",
            ),
            (format!(r#"{{{all}}}"#), "channel 't' missing"),
            ("[1,2]".to_string(), "not a JSON object"),
            ("{\"t\":".to_string(), "not a JSON object: EOF"),
        ] {
            let e = columns(&line).unwrap_err();
            assert!(e.contains(says), "{line}: {e}");
        }
    }
}
