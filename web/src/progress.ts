// A running job's progress as the job page shows it: the fraction the server reports (never one
// made up here), the stage and its message, and, while the fraction stands still (a coast's
// meshing, a deform job's export after its search), a moving bar and the seconds since it last
// moved, so a long stage does not look like a hang.

import type { Job, Progress } from './api';
import { el } from './ui';

/** After this long without a new fraction, the bar shows it is still working. */
const STILL_MS = 1000;

export interface ProgressMeter {
  bar: HTMLProgressElement;
  percent: HTMLElement;
  /** The stage line and the waiting note. */
  line: HTMLElement;
  show(p: Progress): void;
  /** The job ended: its final state in place of the progress. */
  end(job: Job): void;
  note(text: string): void;
}

export function progressMeter(signal: AbortSignal): ProgressMeter {
  const bar = el('progress', { id: 'job-progress', max: '1', value: '0', 'aria-label': 'Progress' }) as HTMLProgressElement;
  const percent = el('span', { id: 'job-percent' });
  const stage = el('span', { id: 'job-stage', class: 'muted' });
  const waiting = el('span', { id: 'job-waiting', class: 'muted', hidden: '' });
  const line = el('div', { class: 'stage-line' }, [el('span', { 'aria-live': 'polite' }, [stage]), ' ', waiting]);
  let fraction = -1;
  let last: Progress | null = null;
  let stageName = '';
  let since = performance.now();
  let done = false;

  const tick = (): void => {
    const still = performance.now() - since;
    const on = !done && fraction < 1 && still >= STILL_MS;
    bar.classList.toggle('waiting', on);
    bar.dataset.waiting = String(on);
    waiting.hidden = !on;
    if (on) {
      const s = Math.floor(still / 1000);
      waiting.dataset.seconds = String(s);
      waiting.textContent = `· working, ${s} s since the last step`;
    }
  };
  const timer = window.setInterval(tick, 500);
  signal.addEventListener('abort', () => clearInterval(timer));

  return {
    bar,
    percent,
    line,
    show(p) {
      if (p.fraction !== fraction || p.stage !== stageName) since = performance.now();
      fraction = p.fraction;
      stageName = p.stage;
      last = p;
      bar.value = p.fraction;
      percent.textContent = `${Math.round(p.fraction * 100)} %`;
      stage.textContent = `${p.stage}${p.steps ? ` — step ${p.step} of ${p.steps}` : ''}${p.message ? `: ${p.message}` : ''}`;
      tick();
    },
    end(job) {
      done = true;
      clearInterval(timer);
      tick();
      if (job.status === 'succeeded') {
        bar.value = 1;
        percent.textContent = '100 %';
        // A search that met its goal early (the result says why it stopped) jumps from its step
        // to the end: say so, rather than leave the jump unexplained or fill it with made-up steps.
        const stopped = job.result?.stopped;
        const early = last && last.steps && last.step < last.steps && typeof stopped === 'string' && stopped !== 'max_iterations';
        stage.textContent = early ? `done — the ${last!.stage} stopped at step ${last!.step} of ${last!.steps} (${stopped}: its goal was met)` : 'done';
      } else if (job.status === 'cancelled') {
        // No fraction: how far it had got is not what a cancelled job is about.
        bar.hidden = true;
        percent.textContent = '';
        stage.textContent = 'cancelled';
      } else {
        bar.value = job.progress.fraction;
        percent.textContent = `${Math.round(job.progress.fraction * 100)} %`;
        stage.textContent = `failed during ${job.progress.stage}`;
      }
    },
    note(text) {
      stage.textContent = text;
    },
  };
}
