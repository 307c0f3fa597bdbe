//! The end checks: every accepted job has ended (none lost), and every artifact of every
//! succeeded job downloads whole with the sha256 the job advertises.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use futures::StreamExt;
use serde_json::Value;
use sha2::{Digest, Sha256};

use crate::report::Checks;
use crate::scenarios::shared;

/// Downloads at once during the checks.
const PARALLEL: usize = 8;

/// The job as stored now (None: not found), asked of the replicas in turn.
async fn fetch(client: &reqwest::Client, n: usize, id: &str) -> Option<Value> {
    let apis = &shared().apis;
    let res = client.get(format!("{}/v1/jobs/{id}", apis[n % apis.len()])).send().await.ok()?;
    if !res.status().is_success() {
        return None;
    }
    res.json().await.ok()
}

fn ended(job: &Value) -> bool {
    matches!(job["status"].as_str(), Some("succeeded" | "failed" | "cancelled"))
}

/// Every accepted job as stored, once all have ended or `within` has passed.
async fn settle(client: &reqwest::Client, within: Duration) -> HashMap<String, Option<Value>> {
    let ids: Vec<String> = shared().accepted.lock().unwrap().iter().map(|a| a.id.clone()).collect();
    let start = Instant::now();
    let mut jobs: HashMap<String, Option<Value>> = HashMap::new();
    loop {
        let open: Vec<String> =
            ids.iter().filter(|id| !jobs.get(*id).and_then(Option::as_ref).is_some_and(ended)).cloned().collect();
        let fetched: Vec<(String, Option<Value>)> = futures::stream::iter(open.into_iter().enumerate())
            .map(|(n, id)| async move {
                let job = fetch(client, n, &id).await;
                (id, job)
            })
            .buffer_unordered(PARALLEL)
            .collect()
            .await;
        for (id, job) in fetched {
            jobs.insert(id, job);
        }
        let waiting = jobs.values().filter(|j| !j.as_ref().is_some_and(ended)).count();
        if waiting == 0 || start.elapsed() > within {
            return jobs;
        }
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
}

/// Wait (at most `within`) until every job accepted so far has ended.
pub async fn drain(client: &reqwest::Client, within: Duration) {
    settle(client, within).await;
}

/// The end checks, and every accepted job as it ended (by id).
pub async fn run(client: &reqwest::Client, within: Duration) -> (Checks, HashMap<String, Value>) {
    let jobs = settle(client, within).await;
    let mut checks = Checks { accepted: jobs.len(), ..Checks::default() };
    let mut downloads = Vec::new();
    for (id, job) in &jobs {
        match job {
            Some(j) if ended(j) => {
                if j["status"] == "succeeded" {
                    checks.succeeded += 1;
                    for a in j["artifacts"].as_array().into_iter().flatten() {
                        let (name, sha, bytes) = (a["name"].as_str(), a["sha256"].as_str(), a["bytes"].as_u64());
                        downloads.push((
                            id.clone(),
                            name.unwrap_or_default().to_string(),
                            sha.unwrap_or_default().to_string(),
                            bytes.unwrap_or(0),
                        ));
                    }
                } else {
                    checks.failed += 1;
                    checks.problems.push(format!("job {id} ({}) ended {}: {}", j["kind"], j["status"], j["error"]));
                }
            }
            _ => {
                checks.lost += 1;
                let accepted = shared().accepted.lock().unwrap();
                let a = accepted.iter().find(|a| &a.id == id);
                let (kind, phase) = a.map_or(("?", "?"), |a| (a.kind.as_str(), a.phase.as_str()));
                checks.problems.push(format!(
                    "job {id} ({kind}, {phase}) lost: {}",
                    if job.is_some() { "never ended" } else { "not found" }
                ));
            }
        }
    }
    let apis = &shared().apis;
    let results: Vec<Option<String>> = futures::stream::iter(downloads.into_iter().enumerate())
        .map(|(n, (id, name, sha, bytes))| async move {
            let url = format!("{}/v1/jobs/{id}/artifacts/{name}", apis[n % apis.len()]);
            let got = match client.get(&url).send().await {
                Ok(r) if r.status().is_success() => r.bytes().await.map_err(|e| e.to_string()),
                Ok(r) => Err(format!("status {}", r.status())),
                Err(e) => Err(e.to_string()),
            };
            match got {
                Ok(b) if b.len() as u64 == bytes && format!("{:x}", Sha256::digest(&b)) == sha => None,
                Ok(b) => {
                    Some(format!("job {id}: {name}: {} bytes not matching its sha256 ({bytes} advertised)", b.len()))
                }
                Err(e) => Some(format!("job {id}: {name}: {e}")),
            }
        })
        .buffer_unordered(PARALLEL)
        .collect()
        .await;
    checks.artifacts_checked = results.len();
    for r in results.into_iter().flatten() {
        checks.artifact_mismatches += 1;
        checks.problems.push(r);
    }
    checks.problems.extend(shared().problems.lock().unwrap().iter().cloned());
    let jobs = jobs.into_iter().filter_map(|(id, j)| Some((id, j?))).collect();
    (checks, jobs)
}
