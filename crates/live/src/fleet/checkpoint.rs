//! A cell's checkpoint in the fleet's store: the record in
//! [`CHECKPOINTS_BUCKET`](super::CHECKPOINTS_BUCKET) under the cell's key — the run, the last
//! frame and its stream sequence, whether the run is done, and the stages' state ([`Stages::checkpoint`](crate::service::Stages::checkpoint)) — written
//! only over the revision this worker wrote (compare and set).
//!
//! **A state larger than a message.** The server refuses a message over its `max_payload` (1 MiB
//! by default; and closes the connection that sent it). A cyclic-torque stage holding its first
//! cycles for the choice takes ≈ 280 kB at `--torque-after 10`, and more with more cycles; so a
//! state that does not fit one value goes into parts first — keys `<cell>.<slot>.<k>`, each at
//! most `max_payload` less [`HEADROOM`] — and the record then names them (their slot, count,
//! length and SHA-256) instead of holding the state. Two slots take turns, so the parts the
//! record names are never the ones being written; a cell id has no `.`, so no other cell's key
//! is touched. Parts that do not add up to the record's length and digest (a writer that lost
//! the cell wrote over them) are refused on reading.
//!
//! **A checkpoint that cannot be taken up** — parts that do not add up, a record that is no
//! checkpoint, a state of another layout (a physid of another version wrote it, as in a
//! fleet's rolling upgrade) — is told on the cell's events subject, and the cell is processed
//! from its run's first frame, as without a checkpoint (`worker::process_cell`).

use super::{nats, Fleet, FleetError};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// What a part leaves of the server's `max_payload` for the message's subject and headers.
pub const HEADROOM: usize = 4096;

/// A cell's checkpoint (MessagePack in [`CHECKPOINTS_BUCKET`](super::CHECKPOINTS_BUCKET)).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct Checkpoint {
    /// The run it belongs to.
    pub run: u64,
    /// The last frame processed.
    pub seq: u64,
    /// Its stream sequence: the next worker reads on from the one after.
    pub stream_seq: u64,
    /// The run's end frame has been processed.
    pub done: bool,
    /// The stages' state (empty when done, or when it is in [`parts`](Self::parts)): a
    /// MessagePack `bin` (an array of numbers, as written before, is read too).
    #[serde(with = "serde_bytes")]
    pub state: Vec<u8>,
    /// Where the state is when it did not fit in the record.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parts: Option<Parts>,
}

/// A state stored in parts (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(super) struct Parts {
    /// 0 or 1: the keys `<cell>.<slot>.<k>`.
    pub slot: u8,
    /// How many parts.
    pub count: u32,
    /// The state's length [bytes].
    pub len: u64,
    /// Its SHA-256, hex.
    pub sha256: String,
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The key of part `k` of `slot`.
fn part_key(cell: &str, slot: u8, k: u32) -> String {
    format!("{cell}.{slot}.{k}")
}

/// The checkpoints of one cell as one worker writes them: the record's revision (compare and
/// set) and the slot its parts are in.
#[derive(Debug, Default)]
pub(super) struct CheckpointWriter {
    revision: Option<u64>,
    slot: Option<u8>,
}

impl CheckpointWriter {
    /// Write `c` over the revision this writer read or wrote last: in the record when it fits,
    /// else its state in parts first (in the slot the record does not name) and then the
    /// record naming them.
    pub async fn put(
        &mut self,
        fleet: &Fleet,
        cell: &str,
        mut c: Checkpoint,
    ) -> Result<(), FleetError> {
        let limit = fleet
            .client
            .server_info()
            .max_payload
            .saturating_sub(HEADROOM)
            .max(HEADROOM);
        let mut bytes = rmp_serde::to_vec(&c)
            .map_err(|e| FleetError::Invalid(format!("writing the checkpoint of {cell}: {e}")))?;
        let mut slot = None;
        if bytes.len() > limit {
            let s = self.slot.map_or(0, |s| 1 - s);
            let state = std::mem::take(&mut c.state);
            let mut count = 0u32;
            for (k, part) in state.chunks(limit).enumerate() {
                let k = u32::try_from(k).unwrap_or(u32::MAX);
                fleet
                    .checkpoints
                    .put(part_key(cell, s, k), part.to_vec().into())
                    .await
                    .map_err(|e| {
                        nats(format!("writing part {k} of the checkpoint of {cell}"))(e.into())
                    })?;
                count = k + 1;
            }
            c.parts = Some(Parts {
                slot: s,
                count,
                len: state.len() as u64,
                sha256: sha256_hex(&state),
            });
            slot = Some(s);
            bytes = rmp_serde::to_vec(&c).map_err(|e| {
                FleetError::Invalid(format!("writing the checkpoint of {cell}: {e}"))
            })?;
        }
        let what =
            format!("writing the checkpoint of {cell} (another worker may have the cell now)");
        let revision = match self.revision {
            Some(r) => fleet
                .checkpoints
                .update(cell, bytes.into(), r)
                .await
                .map_err(|e| nats(what)(e.into()))?,
            None => fleet
                .checkpoints
                .create(cell, bytes.into())
                .await
                .map_err(|e| nats(what)(e.into()))?,
        };
        self.revision = Some(revision);
        self.slot = slot;
        Ok(())
    }
}

/// The checkpoint of `cell` (`Ok(None)`: there is none; `Err`: there is a record this physid
/// cannot read, and why) and a writer that writes over it.
pub(super) async fn read(
    fleet: &Fleet,
    cell: &str,
) -> Result<(Result<Option<Checkpoint>, String>, CheckpointWriter), FleetError> {
    let entry = fleet
        .checkpoints
        .entry(cell)
        .await
        .map_err(|e| nats(format!("reading the checkpoint of {cell}"))(e.into()))?;
    let mut writer = CheckpointWriter {
        revision: entry.as_ref().map(|e| e.revision),
        slot: None,
    };
    let Some(entry) = entry else {
        return Ok((Ok(None), writer));
    };
    let mut c = match rmp_serde::from_slice::<Checkpoint>(&entry.value) {
        Ok(c) => c,
        Err(e) => return Ok((Err(format!("not a checkpoint ({e})")), writer)),
    };
    if let Some(p) = c.parts.take() {
        writer.slot = Some(p.slot);
        match assemble(fleet, cell, &p).await {
            Ok(state) => c.state = state,
            Err(why) => return Ok((Err(why), writer)),
        }
    }
    Ok((Ok(Some(c)), writer))
}

/// The state the parts `p` hold, checked against its length and digest.
async fn assemble(fleet: &Fleet, cell: &str, p: &Parts) -> Result<Vec<u8>, String> {
    let mut state = Vec::with_capacity(usize::try_from(p.len).unwrap_or(0).min(1 << 30));
    for k in 0..p.count {
        let key = part_key(cell, p.slot, k);
        match fleet.checkpoints.get(&key).await {
            Ok(Some(v)) => state.extend_from_slice(&v),
            Ok(None) => return Err(format!("part {key} is missing")),
            Err(e) => return Err(format!("part {key}: {e}")),
        }
    }
    if state.len() as u64 != p.len || sha256_hex(&state) != p.sha256 {
        return Err(format!(
            "its {} parts hold {} bytes that are not the {} bytes it names (SHA-256)",
            p.count,
            state.len(),
            p.len
        ));
    }
    Ok(state)
}

/// Whether `cell`'s run `run` has been processed to its end (the record alone says).
pub(super) async fn finished(fleet: &Fleet, cell: &str, run: u64) -> bool {
    match fleet.checkpoints.get(cell).await {
        Ok(Some(v)) => {
            rmp_serde::from_slice::<Checkpoint>(&v).is_ok_and(|c| c.run == run && c.done)
        }
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(state: Vec<u8>) -> Checkpoint {
        Checkpoint {
            run: 7,
            seq: 3,
            stream_seq: 4,
            done: false,
            state,
            parts: None,
        }
    }

    /// The state is a MessagePack `bin` (its length and the bytes: a byte per byte), and a
    /// record written before, with the state as an array of numbers, still reads.
    #[test]
    fn the_state_is_bytes_and_the_old_layout_reads() {
        let state: Vec<u8> = (0..=255).collect();
        let bytes = rmp_serde::to_vec_named(&record(state.clone())).expect("encode");
        // bin 16 marker (0xc5), the length 256, then the bytes as they are.
        let at = bytes
            .windows(3)
            .position(|w| w == [0xc5, 0x01, 0x00])
            .expect("a bin 16 of 256 bytes");
        assert_eq!(&bytes[at + 3..at + 3 + 256], &state[..]);
        assert_eq!(
            rmp_serde::from_slice::<Checkpoint>(&bytes)
                .expect("decode")
                .state,
            state
        );
        /// The layout before: `state` a sequence of integers.
        #[derive(Serialize)]
        struct Before {
            run: u64,
            seq: u64,
            stream_seq: u64,
            done: bool,
            state: Vec<u8>,
        }
        let old = rmp_serde::to_vec_named(&Before {
            run: 7,
            seq: 3,
            stream_seq: 4,
            done: false,
            state: state.clone(),
        })
        .expect("encode");
        assert!(old.len() > bytes.len(), "the old layout is larger");
        let c = rmp_serde::from_slice::<Checkpoint>(&old).expect("the old layout reads");
        assert_eq!((c.run, c.seq, c.stream_seq, c.state), (7, 3, 4, state));
    }
}
