// What the page's modules share: app.js provides the console's ops, catalog and the commanded-yaw
// marker once the panels are built; the video panel (lib/video.js) uses them, so a click on the
// picture moves the same marker and a tracking stop goes through the same ops as the rest.

let provideApi;
export const consoleReady = new Promise((resolve) => { provideApi = resolve; });

// app.js: { catalog, run(op, args, okText), attempt(op, args), showError(text), motionStart(), motionEnd(seq, yaw|null),
//           refresh(id) (read a command's row back) }
export function provide(api) {
  provideApi(api);
}
