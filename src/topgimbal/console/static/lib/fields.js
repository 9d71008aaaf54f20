// Controls generated from the catalog's field metadata (kind, unit, range, enum table).
// Nothing about a command is hand-coded here: a field's description decides its input.

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

function numberDefault(f) {
  if (f.default != null) return f.default;
  const lo = f.min ?? 0, hi = f.max ?? 0;
  return lo <= 0 && 0 <= hi ? 0 : lo;
}

// One input per field; returns { node, get(), set(values) }.
export function fieldInputs(fields, { prefix = "" } = {}) {
  const wrap = el("span", { class: "inputs" });
  const getters = [];
  const setters = {};
  for (const f of fields || []) {
    if (f.kind === "literal") continue;
    const id = `${prefix}${f.name}`;
    const tip = [f.description, f.allowed].filter(Boolean).join(" — ");
    let input;
    let read;
    if (f.kind === "enum") {
      input = el("select", { "data-field": f.name, "data-testid": `field-${id}`, title: tip });
      for (const v of f.values) input.append(el("option", { value: v.name, text: v.label || v.name }));
      if (f.default != null) input.value = f.default;
      read = () => input.value;
    } else if (f.kind === "number") {
      input = el("input", {
        type: "number", "data-field": f.name, "data-testid": `field-${id}`, title: tip,
        min: f.min, max: f.max, step: f.step ?? "any",
      });
      input.value = numberDefault(f);
      read = () => (input.value === "" ? null : Number(input.value));
    } else if (f.kind === "enum_or_number") {
      const listId = `dl-${id}-${Math.random().toString(36).slice(2, 7)}`;
      const dl = el("datalist", { id: listId });
      for (const v of f.tokens || []) dl.append(el("option", { value: v.name, label: v.label }));
      input = el("input", { type: "text", list: listId, "data-field": f.name, "data-testid": `field-${id}`, title: tip,
                            placeholder: f.number?.allowed || "" });
      input.value = f.default ?? "";
      wrap.append(dl);
      read = () => {
        const t = input.value.trim();
        return t !== "" && !Number.isNaN(Number(t)) ? Number(t) : t;
      };
    } else {
      input = el("input", { type: "text", "data-field": f.name, "data-testid": `field-${id}`, title: tip,
                            placeholder: f.kind === "ipv4" ? "a.b.c.d" : f.allowed || "" });
      if (f.default != null) input.value = f.default;
      read = () => input.value.trim();
    }
    const unit = f.unit ? ` (${f.unit})` : "";
    wrap.append(el("label", { class: "field" }, el("span", { text: f.name + unit }), input));
    getters.push([f.name, read]);
    setters[f.name] = (v) => { if (v != null) input.value = v; };
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

export function formatFields(fields) {
  if (!fields) return "";
  return Object.entries(fields)
    .map(([k, v]) => `${k}=${typeof v === "number" ? +v.toFixed(4) : v === null ? "null" : v}`)
    .join(" ");
}

// A row "title | inputs | Set / Read" for one command, or its reason when unsupported.
// `ctx` = { catalog, run(op, args, okText) -> Promise }.
export function commandRow(ctx, ident, title) {
  const spec = ctx.catalog.commands[ident];
  const row = el("div", { class: "cmdrow", "data-testid": `cmd-${ident}`, "data-cmd": ident });
  const name = title || spec?.title || ctx.catalog.unsupported[ident]?.title || ident;
  row.append(el("span", { class: "title", text: name, title: spec ? `${ident} — ${spec.section}` : ident }));
  if (!spec) {
    const reason = ctx.catalog.unsupported[ident]?.reason || `the ${ctx.catalog.dialect_title} protocol has no ${ident} command`;
    row.classList.add("unsupported");
    row.append(el("span", { class: "inputs", "data-testid": `reason-${ident}`, text: reason }), el("span"));
    return row;
  }
  const wForm = requestForm(spec, "w");
  const rForm = requestForm(spec, "r");
  const inputs = fieldInputs(wForm ? wForm.fields : [], { prefix: `${ident}-` });
  const result = el("span", { class: "small muted", "data-testid": `result-${ident}` });
  const acts = el("span", { class: "acts" });
  if (wForm) {
    acts.append(el("button", {
      "data-testid": `set-${ident}`, text: "Set",
      onclick: () => ctx.run("request", { id: ident, values: inputs.get() }, `${ident} set`),
    }));
  }
  if (rForm) {
    const readArgs = rForm.fields?.length ? {} : undefined;
    row.read = () => ctx.run("request", { id: ident, read: true, values: readArgs }).then((m) => {
      if (m?.fields) {
        inputs.set(m.fields);
        result.textContent = formatFields(m.fields);
      }
    });
    acts.append(el("button", { "data-testid": `read-${ident}`, text: "Read", onclick: () => row.read() }));
  }
  const mid = el("span", { class: "inputs" }, inputs.node, result);
  row.append(mid, acts);
  return row;
}
