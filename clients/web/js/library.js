// The library: stored objects (ListObjects) with an SVG thumbnail of each one's triangulation,
// Add to scene, Delete, and downloads of the mesh files (ExportObject).

import { fromBase64 } from './rpc.js';

/** Concatenates an ExportObject stream into a Blob. */
export async function exportBlob(rpc, id, format) {
  const chunks = await rpc.collect('rheo.v1.ObjectService/ExportObject', { id, format });
  const type = chunks.find((c) => c.mediaType)?.mediaType || 'application/octet-stream';
  return new Blob(
    chunks.map((c) => fromBase64(c.data || '')),
    { type },
  );
}

const DOWNLOADS = [
  ['VTU', 'EXPORT_FORMAT_VTU', 'vtu'],
  ['OBJ', 'EXPORT_FORMAT_OBJ', 'obj'],
  ['STL', 'EXPORT_FORMAT_STL', 'stl'],
];

function sizeText(o) {
  const a = o.boundsMin || {};
  const b = o.boundsMax || {};
  const cm = (k) => (((b[k] || 0) - (a[k] || 0)) * 100).toFixed(1);
  const tets = o.mesh?.tetrahedronCount || 0;
  return `${cm('x')} × ${cm('y')} × ${cm('z')} cm · ${tets} tets`;
}

export class Library {
  /**
   * @param {HTMLElement} list  container of the entries
   * @param {import('./rpc.js').Rpc} rpc
   * @param {{add: (object) => Promise<void>, report: (msg: string) => void}} hooks
   */
  constructor(list, rpc, hooks) {
    this.list = list;
    this.rpc = rpc;
    this.hooks = hooks;
    this.thumbs = new Map(); // object id -> object URL of its SVG
    this.objects = [];
  }

  async refresh() {
    const objects = [];
    let pageToken = '';
    do {
      const resp = await this.rpc.call('rheo.v1.ObjectService/ListObjects', { pageSize: 100, pageToken });
      objects.push(...(resp.objects || []));
      pageToken = resp.nextPageToken || '';
    } while (pageToken);
    this.objects = objects;
    this.render();
    return objects;
  }

  render() {
    this.list.replaceChildren();
    if (!this.objects.length) {
      const empty = document.createElement('p');
      empty.className = 'muted';
      empty.textContent = 'Nothing stored yet. Draw an outline and press Create.';
      this.list.appendChild(empty);
      return;
    }
    for (const o of this.objects) this.list.appendChild(this.entry(o));
  }

  entry(o) {
    const li = document.createElement('article');
    li.className = 'lib-item';
    li.dataset.id = o.id;
    const img = document.createElement('img');
    img.className = 'thumb';
    img.alt = `Triangulation of ${o.name}`;
    this.thumbnail(o.id).then((url) => url && (img.src = url));
    const info = document.createElement('div');
    info.className = 'lib-info';
    const name = document.createElement('div');
    name.className = 'lib-name';
    name.textContent = o.name;
    name.title = o.id;
    const size = document.createElement('div');
    size.className = 'muted small';
    size.textContent = sizeText(o);
    const actions = document.createElement('div');
    actions.className = 'lib-actions';
    const add = document.createElement('button');
    add.type = 'button';
    add.textContent = 'Add to scene';
    add.setAttribute('aria-label', `Add ${o.name} to scene`);
    add.addEventListener('click', () => this.hooks.add(o));
    const del = document.createElement('button');
    del.type = 'button';
    del.className = 'danger';
    del.textContent = 'Delete';
    del.setAttribute('aria-label', `Delete ${o.name}`);
    del.addEventListener('click', () => this.remove(o));
    actions.append(add, del);
    for (const [label, format, ext] of DOWNLOADS) {
      const a = document.createElement('a');
      a.href = '#';
      a.className = 'download';
      a.textContent = label;
      a.setAttribute('aria-label', `Download ${o.name} as ${label}`);
      a.addEventListener('click', (e) => this.download(e, o, format, ext));
      actions.appendChild(a);
    }
    info.append(name, size, actions);
    li.append(img, info);
    return li;
  }

  async thumbnail(id) {
    if (this.thumbs.has(id)) return this.thumbs.get(id);
    try {
      const blob = await exportBlob(this.rpc, id, 'EXPORT_FORMAT_SVG');
      const url = URL.createObjectURL(new Blob([blob], { type: 'image/svg+xml' }));
      this.thumbs.set(id, url);
      return url;
    } catch (e) {
      return null;
    }
  }

  async remove(o) {
    try {
      await this.rpc.call('rheo.v1.ObjectService/DeleteObject', { id: o.id });
      const url = this.thumbs.get(o.id);
      if (url) URL.revokeObjectURL(url);
      this.thumbs.delete(o.id);
      await this.refresh();
    } catch (e) {
      this.hooks.report(`Delete: ${e.message}`);
    }
  }

  async download(e, o, format, ext) {
    e.preventDefault();
    const link = e.currentTarget;
    link.classList.add('busy');
    try {
      const blob = await exportBlob(this.rpc, o.id, format);
      const a = document.createElement('a');
      a.href = URL.createObjectURL(blob);
      a.download = `${(o.name || o.id).replace(/[^\w.-]+/g, '_')}.${ext}`;
      document.body.appendChild(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(a.href), 10000);
    } catch (err) {
      this.hooks.report(`Export ${ext.toUpperCase()}: ${err.message}`);
    } finally {
      link.classList.remove('busy');
    }
  }
}
