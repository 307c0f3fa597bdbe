// A job as the API sees it, so the page teaches the API: the request it was made from and the
// document GET answers, each with the curl command that does the same from a terminal.

import { Job } from '../api';
import { copyBlock, curlCommand } from '../curl';
import { el } from '../ui';

export function apiPanel(job: Job): HTMLElement {
  const json = (v: unknown) => {
    const pre = el('pre', { class: 'copyable json', tabindex: '0' });
    pre.textContent = JSON.stringify(v, null, 2);
    return pre;
  };
  const mesh = job.artifacts.find((a) => a.name === 'mesh.glb');
  const follow = [
    curlCommand('GET', `/v1/jobs/${job.id}`),
    curlCommand('GET', `/v1/jobs/${job.id}/events`).replace('curl -sS', 'curl -sSN'),
    ...(mesh ? [curlCommand('GET', mesh.href).replace('curl -sS', 'curl -sS -o mesh.glb')] : []),
  ].join('\n\n');
  // The request again: the stored body (every default filled in) is a body the server takes.
  const again = copyBlock('job-request-curl', 'as curl', () =>
    job.replay_of ? curlCommand('POST', `/v1/jobs/${job.replay_of}/replay`, { until_step: job.replay_until_step ?? undefined }) : curlCommand('POST', `/v1/jobs/${job.kind}`, job.request),
  );
  const read = copyBlock('job-read-curl', 'these commands', () => follow);
  return el('section', { class: 'api-panel', 'aria-labelledby': 'api-h' }, [
    el('h2', { id: 'api-h' }, ['The API']),
    el('details', { id: 'job-request' }, [
      el('summary', {}, [job.replay_of ? 'Request: a replay' : `Request: POST /v1/jobs/${job.kind}`]),
      json(job.replay_of ? { until_step: job.replay_until_step ?? null } : job.request),
      again.box,
    ]),
    el('details', { id: 'job-response' }, [
      el('summary', {}, [`Response: GET /v1/jobs/${job.id}`]),
      json(job),
      el('p', { class: 'help' }, ['The job, its event stream (server-sent events) and its mesh, from a terminal:']),
      read.box,
    ]),
  ]);
}
