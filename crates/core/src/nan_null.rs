//! JSON has no NaN: serde_json writes a non-finite `f64` as `null`. These read it back as NaN
//! (`#[serde(deserialize_with = "physid_core::nan_null::f64")]`), so a figure "not known yet"
//! survives a round trip through JSON — the live events, a checkpoint, a report.

use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;

/// A number, `null` read as NaN.
pub fn f64<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// A map of numbers, each `null` read as NaN.
pub fn map<'de, D, K>(d: D) -> Result<BTreeMap<K, f64>, D::Error>
where
    D: Deserializer<'de>,
    K: Deserialize<'de> + Ord,
{
    Ok(BTreeMap::<K, Option<f64>>::deserialize(d)?
        .into_iter()
        .map(|(k, v)| (k, v.unwrap_or(f64::NAN)))
        .collect())
}

/// A list of numbers, each `null` read as NaN.
pub fn vec<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    Ok(Vec::<Option<f64>>::deserialize(d)?
        .into_iter()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect())
}

/// A map of lists of numbers, each `null` read as NaN.
pub fn map_vec<'de, D, K>(d: D) -> Result<BTreeMap<K, Vec<f64>>, D::Error>
where
    D: Deserializer<'de>,
    K: Deserialize<'de> + Ord,
{
    Ok(BTreeMap::<K, Vec<Option<f64>>>::deserialize(d)?
        .into_iter()
        .map(|(k, v)| (k, v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect()))
        .collect())
}

#[cfg(test)]
mod tests {
    #[derive(serde::Serialize, serde::Deserialize)]
    struct S {
        #[serde(deserialize_with = "super::f64")]
        x: f64,
        #[serde(deserialize_with = "super::vec")]
        v: Vec<f64>,
    }

    #[test]
    fn nan_goes_out_as_null_and_comes_back_as_nan() {
        let text = serde_json::to_string(&S {
            x: f64::NAN,
            v: vec![1.5, f64::INFINITY],
        })
        .unwrap();
        assert_eq!(text, r#"{"x":null,"v":[1.5,null]}"#);
        let s: S = serde_json::from_str(&text).unwrap();
        assert!(s.x.is_nan() && s.v[0] == 1.5 && s.v[1].is_nan());
    }
}
