// What the page asks the catalog (/api/catalog): which command plays a role (`spec.role`), which
// commands belong to a panel (`spec.group`), what a model lacks and why. The page never names a
// dialect or keeps its own list of identifiers: a new command with a role or group appears by itself.

import { requestForm } from "./fields.js";

const values = (obj) => Object.values(obj || {});

// The supported command playing `role` (the first when several do), or null.
export function byRole(cat, role) {
  return values(cat.commands).find((c) => c.role === role) || null;
}

export function allByRole(cat, role) {
  return values(cat.commands).filter((c) => c.role === role);
}

// Why the model has no command for `role`: the catalog's reason for the dialect's command that
// plays it, or a sentence saying the dialect has none.
export function roleReason(cat, role) {
  const missing = values(cat.unsupported).find((c) => c.role === role);
  return missing ? missing.reason : `the ${cat.dialect_label} has no ${role.replace(/_/g, " ")} command`;
}

// The vendor sections of the unsupported commands playing `roles` (for a tooltip).
export function roleSections(cat, ...roles) {
  return values(cat.unsupported).filter((c) => roles.includes(c.role)).map((c) => c.section).filter(Boolean).join("; ");
}

// Whether the catalog knows the command's layout well enough for generated inputs: it has a
// request form, and no form holds undocumented raw data (those are left to the command builder).
export function rowable(spec) {
  const requests = ["w", "r"].map((rw) => requestForm(spec, rw)).filter(Boolean);
  return requests.length > 0 && !(spec.forms || []).some((f) => (f.fields || []).some((x) => x.kind === "raw"));
}

// The supported commands of a console group that get a generated row, in catalog order, except
// those whose role has its own control on the panel.
export function groupRows(cat, group, exceptRoles = []) {
  return values(cat.commands).filter((c) => c.group === group && !exceptRoles.includes(c.role) && rowable(c));
}

// The commands of a group this model lacks (each shown with its reason).
export function groupMissing(cat, group) {
  return values(cat.unsupported).filter((c) => c.group === group);
}

// The fields of a command's request forms that set `axis` (the catalog's `axis` metadata).
export function axisFields(spec, axis, rw = "w") {
  return (spec?.forms || [])
    .filter((f) => f.rw === rw && f.direction === "request")
    .flatMap((f) => f.fields || [])
    .filter((f) => f.axis === axis);
}

// Whether the device reports something for this command by itself (a response that is not an echo
// of a write, e.g. the target solution TOPOTEK sends as LAT / LON).
export function reportsByItself(spec) {
  return (spec?.forms || []).some((f) => f.direction === "response" && f.rw === "w" && f.role !== "echo");
}

// The response forms of a command that carry data (not echoes).
export function answerForms(spec) {
  return (spec?.forms || []).filter((f) => f.direction === "response" && f.role !== "echo");
}
