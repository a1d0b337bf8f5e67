//! The panel's layout: which plots it shows, which channels each draws, and the time traces'
//! window — chosen on the page (kept in the browser's local storage) or given by a file
//! (`physid live --layout FILE`, the page's starting layout, served at `/api/layout`). A file
//! that names a plot or channel the panel does not have is refused when the panel starts.

use crate::service::LiveError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The panel's plots and the channels (series) each can draw — the page's own table
/// (`assets/panel.js`, `PLOTS`; the browser test checks they agree).
pub const PLOTS: [(&str, &[&str]); 10] = [
    ("k", &["K"]),
    ("b", &["B"]),
    ("speed", &["omega_en", "omega_dy"]),
    ("torque", &["torque_shaft", "torque_engine"]),
    ("pint", &["p_int", "throttle"]),
    ("cycles", &["torque_engine", "torque_shaft"]),
    ("pcyl", &["p_cyl"]),
    ("tcyc", &["torque_engine"]),
    ("friction", &["measured", "predicted", "nominal", "truth"]),
    ("combustion", &["imep", "mfb50_deg"]),
];

/// The longest time-trace window [s] the page keeps.
pub const MAX_WINDOW_S: f64 = 120.0;

/// A layout: `{"plots": {"speed": ["omega_en"], "k": ["K"]}, "window_s": 30}`. Plots not
/// named are hidden (all shown without `plots`); each named plot draws the channels listed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Layout {
    /// The plots shown, each with the channels it draws.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plots: Option<BTreeMap<String, Vec<String>>>,
    /// The time traces' window [s of recording] (the page's default: 10 s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_s: Option<f64>,
}

impl Layout {
    /// Read and check a layout file (JSON).
    pub fn read(path: &std::path::Path) -> Result<Self, LiveError> {
        let p = path.display();
        let text = physid_core::memory::read_small(path, 1 << 20)
            .map_err(|e| LiveError::Invalid(format!("--layout {p}: {e}")))?;
        let layout: Layout = serde_json::from_str(&text).map_err(|e| {
            LiveError::Invalid(format!(
                "--layout {p}: {e} (expected {{\"plots\": {{PLOT: [CHANNEL, …]}}, \"window_s\": S}})"
            ))
        })?;
        layout
            .check()
            .map_err(|e| LiveError::Invalid(format!("--layout {p}: {e}")))?;
        Ok(layout)
    }

    /// Every plot and channel named is one the panel has; the window is in (0, 120] s.
    pub fn check(&self) -> Result<(), String> {
        if let Some(w) = self.window_s {
            if !(w > 0.0 && w <= MAX_WINDOW_S) {
                return Err(format!(
                    "window_s {w}: expected a number of seconds in (0, {MAX_WINDOW_S}]",
                    w = physid_core::Num(w)
                ));
            }
        }
        for (plot, channels) in self.plots.iter().flatten() {
            let Some((_, have)) = PLOTS.iter().find(|(id, _)| id == plot) else {
                let ids: Vec<&str> = PLOTS.iter().map(|(id, _)| *id).collect();
                return Err(format!(
                    "no plot '{plot}'; the panel's plots: {}",
                    ids.join(", ")
                ));
            };
            if let Some(c) = channels.iter().find(|c| !have.contains(&c.as_str())) {
                return Err(format!(
                    "plot '{plot}' has no channel '{c}'; it draws: {}",
                    have.join(", ")
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_layout_names_only_what_the_panel_has() {
        let ok: Layout = serde_json::from_str(
            r#"{"plots": {"speed": ["omega_en"], "k": ["K"]}, "window_s": 30}"#,
        )
        .unwrap();
        assert_eq!(ok.check(), Ok(()));
        let bad = |text: &str| {
            let l: Layout = serde_json::from_str(text).unwrap();
            l.check().unwrap_err()
        };
        assert!(bad(r#"{"plots": {"sped": []}}"#)
            .contains("no plot 'sped'; the panel's plots: k, b, speed"));
        assert!(bad(r#"{"plots": {"speed": ["omega"]}}"#).contains("it draws: omega_en, omega_dy"));
        assert!(bad(r#"{"window_s": 0}"#).contains("window_s 0"));
        assert!(serde_json::from_str::<Layout>(r#"{"plot": {}}"#).is_err());
    }
}
