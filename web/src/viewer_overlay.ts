// What the viewer writes over its picture: the triangle count (top left), the height legend with
// the grid's scale (bottom left) and the full-screen button (top right). The axis gizmo (bottom
// right) is drawn in the canvas itself.

import { el } from './ui';
import { tintGradient } from './hypsometric';

/** Metres as the overlays show them: one decimal below 1 km, whole metres above. */
export function metres(v: number): string {
  return `${Math.abs(v) >= 1000 ? Math.round(v).toLocaleString('en') : v.toFixed(1)} m`;
}

/** A round grid spacing (1, 2 or 5 × 10ⁿ metres) giving about `cells` squares over `extent`. */
export function niceStep(extent: number, cells = 10): number {
  const raw = Math.max(extent, 1e-6) / cells;
  const p = 10 ** Math.floor(Math.log10(raw));
  const f = raw / p;
  return (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * p;
}

export class Overlay {
  readonly stats = el('div', { class: 'viewer-stats', id: 'viewer-stats', 'aria-live': 'polite' });
  readonly legend = el('div', { class: 'viewer-legend', id: 'viewer-legend', role: 'group', 'aria-label': 'Heights' });
  readonly fullscreen = el('button', { type: 'button', class: 'viewer-fullscreen', id: 'fullscreen', 'aria-pressed': 'false' }, ['Full screen']) as HTMLButtonElement;
  private max = el('span', { class: 'legend-max', id: 'legend-max' });
  private bar = el('div', { class: 'legend-bar', 'aria-hidden': 'true' });
  private waterMark = el('div', { class: 'legend-water-mark', 'aria-hidden': 'true' });
  private min = el('span', { class: 'legend-min', id: 'legend-min' });
  private water = el('span', { class: 'legend-water', id: 'legend-water' });
  private grid = el('span', { class: 'legend-grid', id: 'grid-scale' });

  constructor(host: HTMLElement) {
    this.bar.append(this.waterMark);
    this.legend.append(this.max, this.bar, this.min, this.water, this.grid);
    this.legend.hidden = true;
    this.stats.hidden = true;
    host.append(this.stats, this.legend, this.fullscreen);
  }

  /** Triangles and vertices of what is drawn. */
  showCounts(triangles: number, vertices: number): void {
    this.stats.hidden = false;
    this.stats.textContent = triangles === 0 ? 'an empty mesh: nothing is left to show' : `${triangles.toLocaleString('en')} triangles · ${vertices.toLocaleString('en')} vertices`;
  }

  /**
   * The model's lowest and highest points; with `tintSea` (the sea level the server tinted the
   * vertex colours with) the colour ramp beside them, else the heights alone; the water level
   * shown and the grid's spacing when there are.
   */
  showHeights(min: number, max: number, tintSea: number | null, water: number | null, gridStep: number | null): void {
    // An empty mesh (a column weathered away) has no heights: no legend rather than ±∞.
    this.legend.hidden = !(Number.isFinite(min) && Number.isFinite(max));
    if (this.legend.hidden) return;
    Object.assign(this.legend.dataset, { min: min.toFixed(3), max: max.toFixed(3) });
    this.max.textContent = `${tintSea === null ? 'highest ' : ''}${metres(max)}`;
    this.min.textContent = `${tintSea === null ? 'lowest ' : ''}${metres(min)}`;
    this.bar.hidden = tintSea === null;
    this.legend.classList.toggle('plain', tintSea === null);
    if (tintSea !== null) this.bar.style.setProperty('background', tintGradient(min, max, tintSea));
    const inside = water !== null && water > min && water < max;
    this.waterMark.hidden = !inside;
    if (inside) this.waterMark.style.setProperty('bottom', `${(((water - min) / (max - min)) * 100).toFixed(2)}%`);
    this.water.hidden = water === null;
    this.water.textContent = water === null ? '' : `water ${metres(water)}`;
    this.grid.hidden = gridStep === null;
    this.grid.textContent = gridStep === null ? '' : `grid ${metres(gridStep).replace('.0 m', ' m')} squares`;
    if (gridStep === null) delete this.grid.dataset.spacing;
    else this.grid.dataset.spacing = String(gridStep);
  }

  hideHeights(): void {
    this.legend.hidden = true;
  }

  showGrid(on: boolean): void {
    this.grid.classList.toggle('off', !on);
  }
}
