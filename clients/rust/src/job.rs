//! A handle on one job: its document, and what can be done with it.

use bytes::Bytes;
use futures_util::{Stream, StreamExt};
use sha2::{Digest, Sha256};
use tokio::io::AsyncWriteExt;

use crate::{error, Client, Error, Events, JobDocument, JobStatus};

/// A submitted job.
#[derive(Clone, Debug)]
pub struct Job {
    client: Client,
    doc: JobDocument,
}

impl Job {
    pub(crate) fn new(client: Client, doc: JobDocument) -> Self {
        Self { client, doc }
    }

    pub fn id(&self) -> &str {
        &self.doc.id
    }

    /// The document as last read (at submission, or by [`Job::refresh`] / [`Job::wait`]).
    pub fn document(&self) -> &JobDocument {
        &self.doc
    }

    /// Read the document again.
    pub async fn refresh(&mut self) -> Result<&JobDocument, Error> {
        let res = self.client.request(reqwest::Method::GET, &format!("/v1/jobs/{}", self.doc.id)).send().await?;
        self.doc = error::json(res).await?;
        Ok(&self.doc)
    }

    /// The job's events from the start (or after `last_event_id`) to its `done`.
    pub fn events(&self, last_event_id: Option<String>) -> Events {
        Events::new(self.client.clone(), &self.doc.id, last_event_id)
    }

    /// Follow the job to its end and return its document; a job that failed or was cancelled
    /// is [`Error::Ended`] with its document (the problem in `error`).
    pub async fn wait(&self) -> Result<JobDocument, Error> {
        let mut this = self.clone();
        if !this.doc.status.is_terminal() {
            let mut events = this.events(None);
            while let Some(event) = events.next().await {
                if event?.event == "done" {
                    break;
                }
            }
            // `done` carries the job; read it whole (a stream may leave out a large request).
            this.refresh().await?;
        }
        match this.doc.status {
            JobStatus::Succeeded => Ok(this.doc),
            _ => Err(Error::Ended(Box::new(this.doc))),
        }
    }

    /// The answer to an artifact's download, checked.
    async fn artifact_response(&self, name: &str) -> Result<reqwest::Response, Error> {
        let path = format!("/v1/jobs/{}/artifacts/{name}", self.doc.id);
        error::checked(self.client.request(reqwest::Method::GET, &path).send().await?).await
    }

    /// An artifact's bytes as they arrive.
    pub async fn artifact(&self, name: &str) -> Result<impl Stream<Item = Result<Bytes, Error>>, Error> {
        Ok(self.artifact_response(name).await?.bytes_stream().map(|chunk| chunk.map_err(Error::from)))
    }

    /// An artifact's bytes, whole.
    pub async fn artifact_bytes(&self, name: &str) -> Result<Vec<u8>, Error> {
        let mut out = Vec::new();
        let mut stream = std::pin::pin!(self.artifact(name).await?);
        while let Some(chunk) = stream.next().await {
            out.extend_from_slice(&chunk?);
        }
        Ok(out)
    }

    /// An artifact streamed into the file `path`, its sha256 checked against the `ETag` the
    /// server sends; written beside it first and renamed, so a failure leaves no partial file.
    /// Returns its length.
    pub async fn download(&self, name: &str, path: impl AsRef<std::path::Path>) -> Result<u64, Error> {
        let path = path.as_ref();
        let res = self.artifact_response(name).await?;
        let etag = res.headers().get("etag").and_then(|v| v.to_str().ok()).map(|v| v.trim_matches('"').to_string());
        let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let part = path.with_file_name(format!(".{file_name}.part"));
        let written = async {
            let mut file = tokio::fs::File::create(&part).await?;
            let mut hash = Sha256::new();
            let mut stream = std::pin::pin!(res.bytes_stream());
            let mut written = 0;
            while let Some(chunk) = stream.next().await {
                let chunk = chunk?;
                hash.update(&chunk);
                file.write_all(&chunk).await?;
                written += chunk.len() as u64;
            }
            file.flush().await?;
            let sha: String = hash.finalize().iter().map(|b| format!("{b:02x}")).collect();
            match etag {
                Some(e) if e != sha => Err(Error::Protocol(format!("{name}: its sha256 {sha} is not its ETag {e}"))),
                _ => Ok(written),
            }
        }
        .await;
        match written {
            Ok(n) => {
                tokio::fs::rename(&part, path).await?;
                Ok(n)
            }
            Err(e) => {
                let _ = tokio::fs::remove_file(&part).await;
                Err(e)
            }
        }
    }

    /// A new job rebuilding this one's result from its recorded sequence, whole or up to
    /// `until_step`.
    pub async fn replay(&self, until_step: Option<u64>) -> Result<Job, Error> {
        let body = match until_step {
            Some(k) => serde_json::json!({ "until_step": k }),
            None => serde_json::json!({}),
        };
        let path = format!("/v1/jobs/{}/replay", self.doc.id);
        let res = self.client.request(reqwest::Method::POST, &path).json(&body).send().await?;
        Ok(Job::new(self.client.clone(), error::json(res).await?))
    }

    /// Ask the job to stop; returns its document after the request.
    pub async fn cancel(&mut self) -> Result<&JobDocument, Error> {
        let path = format!("/v1/jobs/{}/cancel", self.doc.id);
        self.doc = error::json(self.client.request(reqwest::Method::POST, &path).send().await?).await?;
        Ok(&self.doc)
    }

    /// Remove the job and its artifacts (cancelling it first if it runs).
    pub async fn delete(self) -> Result<(), Error> {
        let path = format!("/v1/jobs/{}", self.doc.id);
        error::checked(self.client.request(reqwest::Method::DELETE, &path).send().await?).await?;
        Ok(())
    }
}
