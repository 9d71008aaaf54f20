// Controls generated from the catalog's field metadata (kind, unit, range, enum table).
// Nothing about a command is hand-coded here: a field's description decides its input.
// What the operator reads is English (`label` of fields and enum values); the catalog's names
// (`palette=white_hot`), the vendor's own term (白热) and section numbers go in tooltips.

export function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v == null || v === false) continue;
    if (k === "class") e.className = v;
    else if (k === "text") e.textContent = v;
    else if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children) if (c != null) e.append(c);
  return e;
}

// The request form of a command for "w" or "r" (the first; a command may have several).
export function requestForm(spec, rw) {
  return (spec?.forms || []).find((f) => f.rw === rw && f.direction === "request") || null;
}

const UNIT_TEXT = { deg: "°", degC: "°C", "deg/s": "°/s" };

export const unitText = (unit) => (unit ? UNIT_TEXT[unit] ?? unit : "");

// The English label of an enum value (the catalog's name when it has no label).
function valueLabel(v) {
  return v.label || v.name;
}

// A tooltip for an enum value: its vendor term, then the catalog's name and code.
function valueTip(v) {
  return [v.vendor_term, `${v.name} (${v.raw})`].filter(Boolean).join(" — ");
}

// A placeholder short enough to show whole (the full `allowed` text is in the tooltip).
function shortAllowed(allowed) {
  return (allowed || "").split(/ \(|; /)[0];
}

// Wide enough for its placeholder, never narrower than the stylesheet's text inputs.
function fitWidth(placeholder) {
  return `width: max(130px, ${placeholder.length + 4}ch)`;
}

function numberDefault(f) {
  if (f.default != null) return f.default;
  const lo = f.min ?? 0, hi = f.max ?? 0;
  return lo <= 0 && 0 <= hi ? 0 : lo;
}

// One input per field; returns { node, get(), set(values) }.
// `unknown`: the fields are a setting the camera holds (a readable command): until the camera says
// its value, a select shows "not read" and a number is empty, never a default the camera never gave
// (issue 35.6: a page opened while the camera was LOST showed "White hot" and 0).
export function fieldInputs(fields, { prefix = "", unknown = false } = {}) {
  const wrap = el("span", { class: "inputs" });
  const getters = [];
  const setters = {};
  for (const f of fields || []) {
    if (f.kind === "literal") continue;
    const id = `${prefix}${f.name}`;
    const tip = [f.name, f.description, f.allowed].filter(Boolean).join(" — ");
    let input;
    let read;
    if (f.kind === "enum") {
      input = el("select", { "data-field": f.name, "data-testid": `field-${id}`, title: tip });
      if (unknown) input.append(el("option", { value: "", text: "– not read", disabled: true, selected: true }));
      for (const v of f.values) {
        input.append(el("option", { value: v.name, text: valueLabel(v), title: valueTip(v),
                                     "data-vendor-term": v.vendor_term }));
      }
      if (f.default != null && !unknown) input.value = f.default;
      else if (unknown) input.value = "";
      // the select's own tooltip names the chosen value's vendor term too
      const sel = input;
      const retitle = () => { sel.title = [sel.selectedOptions[0]?.title, tip].filter(Boolean).join(" — "); };
      input.addEventListener("change", retitle);
      retitle();
      read = () => input.value;
    } else if (f.kind === "number") {
      input = el("input", {
        type: "number", "data-field": f.name, "data-testid": `field-${id}`, title: tip,
        min: f.min, max: f.max, step: f.step ?? "any",
      });
      if (unknown) input.placeholder = "–";
      else input.value = numberDefault(f);
      read = () => (input.value === "" ? null : Number(input.value));
    } else if (f.kind === "enum_or_number") {
      const listId = `dl-${id}-${Math.random().toString(36).slice(2, 7)}`;
      const dl = el("datalist", { id: listId });
      for (const v of f.tokens || []) dl.append(el("option", { value: v.name, label: valueLabel(v) }));
      const n = f.number;
      const placeholder = n && n.min != null ? `${n.min}..${n.max}${unitText(n.unit) ? " " + unitText(n.unit) : ""} or an action` : "number or action";
      input = el("input", { type: "text", list: listId, "data-field": f.name, "data-testid": `field-${id}`, title: tip,
                            placeholder, style: fitWidth(placeholder) });
      input.value = unknown ? "" : f.default ?? "";
      wrap.append(dl);
      read = () => {
        const t = input.value.trim();
        return t !== "" && !Number.isNaN(Number(t)) ? Number(t) : t;
      };
    } else {
      const placeholder = f.kind === "ipv4" ? "a.b.c.d" : shortAllowed(f.allowed);
      input = el("input", { type: "text", "data-field": f.name, "data-testid": `field-${id}`, title: tip,
                            placeholder, style: fitWidth(placeholder) });
      if (f.default != null && !unknown) input.value = f.default;
      read = () => input.value.trim();
    }
    const unit = f.unit ? ` (${unitText(f.unit)})` : "";
    wrap.append(el("label", { class: "field", title: tip }, el("span", { text: (f.label || f.name) + unit }), input));
    getters.push([f.name, read]);
    setters[f.name] = (v) => {
      if (v == null) return;
      // a select keeps its choice when the camera names a value it has no option for
      if (input.tagName === "SELECT" && ![...input.options].some((o) => o.value === String(v))) return;
      input.value = v;
      input.dispatchEvent(new Event("change"));
    };
  }
  return {
    node: wrap,
    get() {
      const out = {};
      for (const [name, read] of getters) {
        const v = read();
        if (v !== null && v !== "") out[name] = v;
      }
      return out;
    },
    set(values) {
      for (const [k, v] of Object.entries(values || {})) setters[k]?.(v);
    },
  };
}

// Field metadata by name, over every form of a command (request and response forms share names).
export function fieldMeta(spec) {
  const out = {};
  for (const form of spec?.forms || []) for (const f of form.fields || []) out[f.name] ??= f;
  return out;
}

function valueText(meta, v) {
  if (v === null || v === undefined) return "–";
  const table = meta?.values || meta?.tokens;
  const entry = table?.find((x) => x.name === v);
  if (entry) return valueLabel(entry);
  if (typeof v === "number") {
    const unit = unitText(meta?.unit || meta?.number?.unit);
    const n = +v.toFixed(4);
    return unit ? (unit.startsWith("°") ? `${n}${unit}` : `${n} ${unit}`) : String(n);
  }
  return String(v);
}

// "Palette: White hot · Interval: 10 s" for the operator, from a command's answer; the raw
// `name=value` text (formatFields) is what tooltips and the traffic pane show.
// With `single`, an answer of one field is just its value ("White hot" next to "Thermal palette").
export function describeFields(spec, fields, { single = false } = {}) {
  if (!fields) return "";
  const meta = fieldMeta(spec);
  const entries = Object.entries(fields).filter(([k]) => meta[k]?.kind !== "literal");
  if (single && entries.length === 1) return valueText(meta[entries[0][0]], entries[0][1]);
  return entries.map(([k, v]) => `${meta[k]?.label || k}: ${valueText(meta[k], v)}`).join(" · ");
}

// The vendor terms of the enum values in `fields` (for a tooltip), e.g. "palette: 白热".
export function vendorTerms(spec, fields) {
  const meta = fieldMeta(spec);
  return Object.entries(fields || {})
    .map(([k, v]) => [k, (meta[k]?.values || meta[k]?.tokens)?.find((x) => x.name === v)?.vendor_term])
    .filter(([, t]) => t)
    .map(([k, t]) => `${k}: ${t}`)
    .join(", ");
}

export function formatFields(fields) {
  if (!fields) return "";
  return Object.entries(fields)
    .map(([k, v]) => `${k}=${typeof v === "number" ? +v.toFixed(4) : v === null ? "null" : v}`)
    .join(" ");
}

// Why the model cannot use command `ident` (the catalog's reason, without section numbers).
export function reasonFor(catalog, ident) {
  return catalog.unsupported[ident]?.reason || `the ${catalog.dialect_label} has no ${ident} command`;
}

// An answer shown to the operator: English labels, the raw fields and vendor terms as tooltip.
export function showResult(node, spec, fields) {
  node.textContent = describeFields(spec, fields, { single: true });
  node.title = [formatFields(fields), vendorTerms(spec, fields)].filter(Boolean).join(" — ");
  node.dataset.raw = formatFields(fields);
}

// A row "title | inputs | Set / Read" for one command, or its reason when unsupported.
// `ctx` = { catalog, run(op, args, okText) -> Promise, attempt(op, args) -> Promise<{ok, result | error}>, toast }.
// The row element gets `show(fields)` (what the camera said), `read()` and, when readable, `readBack()`.
export function commandRow(ctx, ident, title) {
  const spec = ctx.catalog.commands[ident];
  const row = el("div", { class: "cmdrow", "data-testid": `cmd-${ident}`, "data-cmd": ident });
  const name = title || spec?.title || ctx.catalog.unsupported[ident]?.title || ident;
  const section = spec?.section || ctx.catalog.unsupported[ident]?.section;
  row.append(el("span", { class: "title", text: name, title: section ? `${ident} — ${section}` : ident }));
  if (!spec) {
    const reason = reasonFor(ctx.catalog, ident);
    row.classList.add("unsupported");
    row.append(el("span", { class: "inputs", "data-testid": `reason-${ident}`, text: reason, title: section || "" }), el("span"));
    return row;
  }
  const wForm = requestForm(spec, "w");
  const rForm = requestForm(spec, "r");
  // a query that takes arguments (and has no write) gets inputs for them
  const asks = !wForm && (rForm?.fields || []).length > 0;
  const holds = !!(wForm && rForm && !asks);  // a setting the camera holds: unknown until read
  const inputs = fieldInputs(wForm ? wForm.fields : asks ? rForm.fields : [], { prefix: `${ident}-`, unknown: holds });
  const result = el("span", { class: "small muted", "data-testid": `result-${ident}` });
  const acts = el("span", { class: "acts" });
  // What the row shows is what the camera last said: its answer, the value read back after a Set,
  // or (a command that cannot be read) the Set's echo; a refusal shows the camera's value and why.
  row.show = (fields, { refused = null, echo = false, heard = false } = {}) => {
    // an answer seen in the traffic that repeats what the row shows keeps its note (a refusal)
    if (heard && fields && result.dataset.raw === formatFields(fields)) return;
    if (fields && Object.keys(fields).length) {
      if (!asks) inputs.set(fields);
      showResult(result, spec, fields);
      if (echo) result.textContent += " (the camera's echo)";
    } else {
      result.textContent = "";
    }
    if (refused) result.textContent = `${result.textContent ? result.textContent + " — " : ""}not set: ${refused}`;
    result.classList.toggle("bad", !!refused);
    result.dataset.state = refused ? "refused" : echo ? "echo" : "camera";
  };
  const readable = rForm && !asks;
  if (wForm) {
    acts.append(el("button", {
      "data-testid": `set-${ident}`, text: "Set",
      onclick: async () => {
        const r = await ctx.attempt("request", { id: ident, values: inputs.get() });
        if (r.ok) ctx.toast(`${ident} set`, "ok", 2500);
        const why = r.ok ? null : r.error.message || String(r.error);
        if (readable) {
          const m = await ctx.run("request", { id: ident, read: true });
          if (m?.fields) return row.show(m.fields, { refused: why });
        }
        if (r.ok) row.show(r.result?.fields, { echo: true });
        else row.show(null, { refused: why });
      },
    }));
  }
  if (rForm) {
    row.read = () => ctx.run("request", { id: ident, read: true, values: asks ? inputs.get() : undefined }).then((m) => {
      if (m?.fields) row.show(m.fields);
    });
    if (readable) {
      let pending = null; // reads asked for within a moment of each other are one read
      row.readBack = () => (pending ??= new Promise((ok) => setTimeout(ok, 150)).then(row.read).finally(() => { pending = null; }));
    }
    acts.append(el("button", { "data-testid": `read-${ident}`, text: "Read", onclick: () => row.read() }));
  }
  const mid = el("span", { class: "inputs" }, inputs.node, result);
  row.append(mid, acts);
  return row;
}
