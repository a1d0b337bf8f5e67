//! Whether a recording's time only goes forward, checked as its chunks come. The verbs that
//! take rows in the file's order whatever their times (`identify`, `estimate`) say so when the
//! time goes back or repeats, rather than passing over it in silence.

/// Counts of the samples whose time goes back or repeats the one before, across chunks.
#[derive(Debug, Clone, Default)]
pub struct TimeOrder {
    prev: Option<f64>,
    seen: usize,
    back: usize,
    repeats: usize,
    first: Option<usize>,
}

impl TimeOrder {
    /// Take the next chunk's times.
    pub fn push(&mut self, t: &[f64]) {
        for (i, &now) in t.iter().enumerate() {
            if let Some(before) = self.prev {
                if now < before {
                    self.back += 1;
                } else if now == before {
                    self.repeats += 1;
                } else {
                    self.prev = Some(now);
                    continue;
                }
                self.first.get_or_insert(self.seen + i);
            }
            self.prev = Some(now);
        }
        self.seen += t.len();
    }

    /// What to say when the time did not only go forward.
    pub fn note(&self) -> Option<String> {
        let first = self.first?;
        Some(format!(
            "the time goes back at {} sample(s) and repeats at {} (the first at sample {first}): \
             the rows were taken in the file's order as they are; check with physid inspect",
            self.back, self.repeats
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::TimeOrder;

    #[test]
    fn back_and_repeated_times_are_counted_across_chunks() {
        let mut o = TimeOrder::default();
        o.push(&[0.0, 0.1, 0.2]);
        assert_eq!(o.note(), None);
        o.push(&[0.2, 0.3]); // sample 3 repeats sample 2
        o.push(&[0.25, 0.4]); // sample 5 goes back
        let n = o.note().unwrap();
        assert!(
            n.starts_with(
                "the time goes back at 1 sample(s) and repeats at 1 (the first at sample 3)"
            ),
            "{n}"
        );
    }
}
