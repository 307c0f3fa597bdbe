//! Artifact bytes, kept in chunks of at most [`CHUNK_BYTES`] (one row each), so that neither
//! storing an artifact nor serving it needs a second whole copy in memory: a download reads one
//! chunk at a time, a range only the chunks it covers.

use super::StoreError;

/// The size of a stored chunk. 1 MiB: small enough that a download holds little at once,
/// large enough that a 150 MB artifact is 150 rows.
pub const CHUNK_BYTES: usize = 1 << 20;

/// Where a job's artifact bytes are read from, a piece at a time.
pub trait ArtifactStore: Send + Sync + 'static {
    /// At most `len` bytes of the artifact from byte `offset` (fewer past its end, none at or
    /// after it); `None` when the job has no artifact of that name.
    fn read_artifact(&self, id: &str, name: &str, offset: u64, len: usize) -> Result<Option<Vec<u8>>, StoreError>;

    /// The whole artifact and its media type, for what the service itself reads back whole
    /// (a sequence to replay, a heightfield to start from).
    fn artifact(&self, id: &str, name: &str) -> Result<Option<(String, Vec<u8>)>, StoreError>;
}

/// An artifact's row: what a read needs to know before it reads any bytes.
pub(super) struct StoredArtifact {
    pub media_type: String,
    pub total: i64,
    /// The size of its chunks in the database (when it has no object key).
    pub chunk: i64,
    /// Where its bytes are in the object store, if they are there.
    pub object_key: Option<String>,
}

/// The columns `StoredArtifact` is read from, in its order.
pub(super) const STORED_ARTIFACT: &str = "SELECT media_type, bytes, chunk_bytes, object_key FROM artifacts";

/// The chunks an artifact is stored as, numbered from 0. An empty artifact has none.
pub(super) fn chunks(bytes: &[u8]) -> impl Iterator<Item = (i64, &[u8])> {
    bytes.chunks(CHUNK_BYTES).enumerate().map(|(i, c)| (i as i64, c))
}

/// The chunks that hold bytes `offset .. offset + len` of an artifact of `total` bytes stored
/// in chunks of `chunk` bytes, and where those bytes lie in them once joined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Span {
    pub first_seq: i64,
    pub last_seq: i64,
    /// Bytes of the first chunk before `offset`.
    pub skip: usize,
    pub take: usize,
}

/// `None` when the range is empty (at or past the end, or `len` 0).
pub(super) fn span(total: u64, chunk: u64, offset: u64, len: usize) -> Result<Option<Span>, StoreError> {
    if chunk == 0 {
        return Err(StoreError::Corrupt(format!("an artifact of {total} bytes has chunks of 0 bytes")));
    }
    if offset >= total || len == 0 {
        return Ok(None);
    }
    let end = offset.saturating_add(len as u64).min(total); // exclusive
    let first_seq = offset / chunk;
    Ok(Some(Span {
        first_seq: first_seq as i64,
        last_seq: ((end - 1) / chunk) as i64,
        skip: (offset - first_seq * chunk) as usize,
        take: (end - offset) as usize,
    }))
}

/// Join the chunks of `span`, read in order, into the bytes it stands for.
pub(super) fn assemble(span: &Span, chunks: impl IntoIterator<Item = Vec<u8>>) -> Result<Vec<u8>, StoreError> {
    let mut out = Vec::with_capacity(span.take);
    let mut skip = span.skip;
    for c in chunks {
        let from = skip.min(c.len());
        skip -= from;
        let want = span.take - out.len();
        out.extend_from_slice(&c[from..c.len().min(from + want)]);
        if out.len() == span.take {
            break;
        }
    }
    if out.len() != span.take {
        return Err(StoreError::Corrupt(format!(
            "an artifact's chunks {}..={} hold {} of the {} bytes asked for",
            span.first_seq,
            span.last_seq,
            out.len(),
            span.take
        )));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every range of a small artifact, split into chunks of every size, reads back as the
    /// same slice of the original.
    #[test]
    fn any_range_of_any_chunking_reads_back_the_same_bytes() {
        let data: Vec<u8> = (0..37u8).collect();
        for chunk in [1usize, 2, 5, 36, 37, 100] {
            let stored: Vec<Vec<u8>> = data.chunks(chunk).map(<[u8]>::to_vec).collect();
            for offset in 0..40u64 {
                for len in 0..40usize {
                    let got = match span(data.len() as u64, chunk as u64, offset, len).unwrap() {
                        None => Vec::new(),
                        Some(s) => {
                            let picked = stored[s.first_seq as usize..=s.last_seq as usize].to_vec();
                            assemble(&s, picked).unwrap()
                        }
                    };
                    let from = (offset as usize).min(data.len());
                    let to = (from + len).min(data.len());
                    assert_eq!(got, &data[from..to], "chunk {chunk} offset {offset} len {len}");
                }
            }
        }
    }

    #[test]
    fn missing_chunks_are_corruption_not_short_reads() {
        let s = span(10, 4, 2, 8).unwrap().unwrap();
        assert_eq!((s.first_seq, s.last_seq, s.skip, s.take), (0, 2, 2, 8));
        assert!(matches!(assemble(&s, vec![vec![0; 4], vec![0; 4]]), Err(StoreError::Corrupt(_))));
        assert!(span(10, 0, 0, 1).is_err());
    }
}
