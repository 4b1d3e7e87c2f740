// "Tune it live": the selected instance's parameters from ListParameters, each as a slider and a
// number (both named by the parameter's API name), presets, and the run controls.

const RANGE_STEPS = 1000;

/**
 * The low end of a log-scaled slider, or null for a linear one. Ranges over more than two
 * decades walk logarithmically; one starting at 0 walks from a millionth of its top (slider 0
 * is still exactly 0).
 */
function logLow(p) {
  const lo = p.min > 0 ? p.min : p.max * 1e-6;
  return p.max > 0 && p.min >= 0 && p.max / lo > 100 ? lo : null;
}

function toSlider(p, v) {
  const lo = logLow(p);
  let t;
  if (lo === null) t = (v - p.min) / (p.max - p.min || 1);
  else t = v <= lo ? (v <= p.min ? 0 : 1 / RANGE_STEPS) : Math.log(v / lo) / Math.log(p.max / lo);
  return Math.round(Math.min(1, Math.max(0, t)) * RANGE_STEPS);
}

function fromSlider(p, s) {
  const lo = logLow(p);
  const t = s / RANGE_STEPS;
  if (s <= 0) return p.min;
  const v = lo === null ? p.min + t * (p.max - p.min) : lo * Math.pow(p.max / lo, t);
  return Number(v.toPrecision(4));
}

export function formatValue(v) {
  if (!Number.isFinite(v)) return String(v);
  if (v === 0) return '0';
  const a = Math.abs(v);
  return a >= 1e5 || a < 1e-3 ? v.toExponential(3) : String(Number(v.toPrecision(5)));
}

function msText(ms) {
  return ms >= 1000 ? `${(ms / 1000).toFixed(1)} s` : `${ms >= 10 ? Math.round(ms) : ms.toFixed(1)} ms`;
}

/**
 * SceneObject.multi_rate in words: "multi-rate: the 64 nodes near the tool every tick, the whole
 * every 10 ticks (its last step took 49 ms), 2.4 s behind real time". '' when not multi-rate.
 */
export function multiRateText(mr) {
  if (!mr) return '';
  const nodes = Number(mr.patchInnerNodes || 0);
  const period = Number(mr.periodTicks || 0);
  const step = Number(mr.wholeStepMs || 0);
  const predicted = Number(mr.predictedWholeStepMs || 0);
  const lag = Number(mr.wholeLagMs || 0);
  const patch = nodes ? `the ${nodes} nodes near the tool every tick` : 'the nodes near the tool every tick';
  const whole = `the whole every ${period === 1 ? 'tick' : `${period} ticks`}`;
  const cost = step > 0 ? ` (its last step took ${msText(step)})` : predicted > 0 ? ` (a step predicted at ${msText(predicted)})` : '';
  const behind = lag >= 1 ? `${msText(lag)} behind real time` : 'keeping up with real time';
  return `multi-rate: ${patch}, ${whole}${cost}, ${behind}`;
}

/** The rest of SceneObject.multi_rate, for a tooltip. */
function multiRateDetails(mr) {
  const n = (k) => Number(mr[k] || 0);
  return [
    `patch: ${n('patchInnerNodes')} nodes, ${n('patchTets')} tetrahedra, built ${n('patchRebuilds')} times`,
    `whole step: last ${msText(n('wholeStepMs'))}, longest ${msText(n('wholeStepMaxMs'))}, predicted ${msText(n('predictedWholeStepMs'))}, ${n('wholeSubsteps')} substeps`,
    `syncs ${n('syncs')}, ticks late ${n('lateTicks')}, whole restores ${n('wholeRestores')}`,
    `load averaged over ${msText(n('wholeWindowMs'))}; ${msText(n('wholeLagMs'))} behind real time`,
  ].join('\n');
}

export class ParamsPanel {
  /**
   * @param {HTMLElement} root  the panel's container
   * @param {import('./rpc.js').Rpc} rpc
   * @param {(msg: string) => void} report  shows an error to the user
   */
  constructor(root, rpc, report) {
    this.root = root;
    this.rpc = rpc;
    this.report = report;
    this.select = root.querySelector('#param-instance');
    this.list = root.querySelector('#param-list');
    this.presets = root.querySelector('#param-presets');
    this.multiRate = root.querySelector('#param-multirate');
    this.objects = []; // SceneObjects of the last GetScene
    this.instanceId = 0;
    this.rows = new Map(); // name -> {param, slider, number, server}
    this.pending = new Map(); // name -> value waiting for the debounce
    this.timer = null;
    this.userChose = false; // until the user picks one, the newest object is shown
    this.select.addEventListener('change', () => {
      this.userChose = true;
      this.show(Number(this.select.value));
      this.showMultiRate();
    });
  }

  /** Whether an object of the last GetScene runs multi-rate (its figures change as it runs). */
  get anyMultiRate() {
    return this.objects.some((o) => o.multiRate);
  }

  optionText(o) {
    return `#${o.instanceId} ${o.preset || ''}${o.multiRate ? ' · multi-rate' : ''}`.trim();
  }

  /** The multi-rate line of the chosen object (hidden for the others and the scene). */
  showMultiRate() {
    if (!this.multiRate) return;
    const o = this.objects.find((x) => x.instanceId === this.instanceId);
    const text = o ? multiRateText(o.multiRate) : '';
    this.multiRate.hidden = !text;
    if (this.multiRate.textContent !== text) this.multiRate.textContent = text;
    this.multiRate.title = text ? multiRateDetails(o.multiRate) : '';
  }

  /** GetScene again for the multi-rate figures only: the options' labels and the line. */
  async refreshMultiRate() {
    const scene = await this.rpc.call('rheo.v1.SceneService/GetScene', {});
    this.objects = scene.objects || [];
    for (const opt of this.select.options) {
      const o = this.objects.find((x) => String(x.instanceId) === opt.value);
      if (o && opt.textContent !== this.optionText(o)) opt.textContent = this.optionText(o);
    }
    this.showMultiRate();
    return scene;
  }

  /** Refreshes the instance selector from GetScene; keeps or picks the selection. */
  async refreshScene(prefer) {
    const scene = await this.rpc.call('rheo.v1.SceneService/GetScene', {});
    const objects = scene.objects || [];
    if (prefer !== undefined) this.userChose = false;
    const ids = objects.map((o) => o.instanceId);
    const newest = ids.length ? ids[ids.length - 1] : 0;
    const keep = prefer ?? (this.userChose ? this.instanceId : newest);
    this.select.replaceChildren();
    this.objects = objects;
    for (const o of objects) {
      const opt = document.createElement('option');
      opt.value = String(o.instanceId);
      opt.textContent = this.optionText(o);
      if (o.multiRate) opt.title = multiRateText(o.multiRate);
      this.select.appendChild(opt);
    }
    const scenOpt = document.createElement('option');
    scenOpt.value = '0';
    scenOpt.textContent = 'Scene (gravity, floor)';
    this.select.appendChild(scenOpt);
    const chosen = ids.includes(keep) || keep === 0 ? keep : newest;
    this.select.value = String(chosen);
    // Rebuilding an unchanged panel would throw away a slider the user is moving.
    if (chosen !== this.instanceId || !this.rows.size) await this.show(chosen);
    this.showMultiRate();
    return scene;
  }

  async show(instanceId) {
    this.instanceId = instanceId;
    let resp;
    try {
      resp = await this.rpc.call('rheo.v1.SceneService/ListParameters', { instanceId });
    } catch (e) {
      this.list.replaceChildren();
      this.report(`Parameters: ${e.message}`);
      return;
    }
    this.rows.clear();
    this.list.replaceChildren();
    for (const p of resp.parameters || []) this.addRow(p);
    this.presets.replaceChildren();
    for (const name of resp.presets || []) {
      const b = document.createElement('button');
      b.type = 'button';
      b.className = 'chip';
      b.textContent = name;
      b.setAttribute('aria-label', `Preset ${name}`);
      b.addEventListener('click', () => this.send([], name));
      this.presets.appendChild(b);
    }
    this.presets.hidden = !(resp.presets || []).length || instanceId === 0;
  }

  addRow(p) {
    const row = document.createElement('div');
    row.className = 'param';
    const label = document.createElement('div');
    label.className = 'param-name';
    label.innerHTML = `<code></code> <span class="unit"></span>`;
    label.querySelector('code').textContent = p.name;
    label.querySelector('.unit').textContent = p.unit ? `[${p.unit}]` : '';
    label.title = p.description || '';
    const slider = document.createElement('input');
    slider.type = 'range';
    slider.min = '0';
    slider.max = String(RANGE_STEPS);
    slider.step = '1';
    slider.value = String(toSlider(p, p.value));
    slider.setAttribute('aria-label', p.name);
    slider.title = `${p.description || p.name} (${formatValue(p.min)} to ${formatValue(p.max)} ${p.unit || ''})`;
    const number = document.createElement('input');
    number.type = 'number';
    number.min = String(p.min);
    number.max = String(p.max);
    number.step = 'any';
    number.value = formatValue(p.value);
    number.setAttribute('aria-label', p.name);
    const server = document.createElement('output');
    server.className = 'param-server';
    server.title = 'value the daemon runs with';
    server.textContent = formatValue(p.value);
    const range = document.createElement('div');
    range.className = 'param-range';
    range.textContent = `${formatValue(p.min)} … ${formatValue(p.max)}`;
    const desc = document.createElement('div');
    desc.className = 'param-desc';
    desc.textContent = p.description || '';
    row.append(label, server, slider, number, range, desc);
    this.list.appendChild(row);
    const r = { param: p, slider, number, server };
    this.rows.set(p.name, r);
    slider.addEventListener('input', () => {
      const v = fromSlider(p, Number(slider.value));
      number.value = formatValue(v);
      this.queue(p.name, v);
    });
    number.addEventListener('change', () => {
      const v = Number(number.value);
      if (!Number.isFinite(v)) return;
      slider.value = String(toSlider(p, v));
      this.queue(p.name, v);
    });
  }

  queue(name, value) {
    this.pending.set(name, value);
    clearTimeout(this.timer);
    this.timer = setTimeout(() => {
      const params = [...this.pending].map(([n, v]) => ({ name: n, value: v }));
      this.pending.clear();
      this.send(params, '');
    }, 120);
  }

  /** SetParameters while the scene runs; shows what the daemon answered. */
  async send(parameters, preset) {
    const instanceId = this.instanceId;
    try {
      const resp = await this.rpc.call('rheo.v1.SceneService/SetParameters', { instanceId, parameters, preset });
      if (instanceId !== this.instanceId) return;
      for (const p of resp.parameters || []) {
        const r = this.rows.get(p.name);
        if (!r) continue;
        r.server.textContent = formatValue(p.value);
        r.server.classList.remove('flash');
        void r.server.offsetWidth; // restart the highlight animation
        r.server.classList.add('flash');
        if (preset || !parameters.some((q) => q.name === p.name)) {
          r.slider.value = String(toSlider(r.param, p.value));
          r.number.value = formatValue(p.value);
        }
      }
    } catch (e) {
      this.report(`${e.codeName || 'Error'}: ${e.message}`);
      this.show(instanceId); // back to the values that run
    }
  }
}
