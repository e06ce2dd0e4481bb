// Foxglove Studio 1.48 as a static web page: the App of @foxglove/studio-base (its last
// open-source build, a UMD bundle that puts its exports on `window`) with an in-memory layout
// store, settings in localStorage and no sign-in, telemetry or update checks.
//
// URL parameters: Foxglove's own deep links (`ds=remote-file&ds.url=<mcap url>`, `layoutId`,
// `time`), plus `amexLayout=<url of a layout JSON>`: that layout is stored under the id
// "amex" and selected (amex-log view passes both).
/* global React, ReactDOM */
"use strict";

const S = window;
const LAYOUT_ID = "amex";

class LocalStorageAppConfiguration {
  constructor(defaults) {
    this.defaults = defaults;
    this.listeners = new Map();
  }
  get(key) {
    const text = localStorage.getItem(`studio.app-configuration.${key}`);
    return text == null ? this.defaults[key] : JSON.parse(text);
  }
  async set(key, value) {
    localStorage.setItem(`studio.app-configuration.${key}`, JSON.stringify(value));
    for (const cb of this.listeners.get(key) ?? []) cb(value);
  }
  addChangeListener(key, cb) {
    if (!this.listeners.has(key)) this.listeners.set(key, new Set());
    this.listeners.get(key).add(cb);
  }
  removeChangeListener(key, cb) {
    this.listeners.get(key)?.delete(cb);
  }
}

class MemoryLayoutStorage {
  constructor() {
    this.namespaces = new Map();
  }
  ns(namespace) {
    if (!this.namespaces.has(namespace)) this.namespaces.set(namespace, new Map());
    return this.namespaces.get(namespace);
  }
  async list(namespace) {
    return [...this.ns(namespace).values()];
  }
  async get(namespace, id) {
    return this.ns(namespace).get(id);
  }
  async put(namespace, layout) {
    this.ns(namespace).set(layout.id, layout);
    return layout;
  }
  async delete(namespace, id) {
    this.ns(namespace).delete(id);
  }
  async importLayouts({ fromNamespace, toNamespace }) {
    for (const layout of this.ns(fromNamespace).values()) this.ns(toNamespace).set(layout.id, layout);
  }
  async migrateUnnamespacedLayouts() {}
}

async function main() {
  const params = new URL(window.location.href).searchParams;
  const layoutStorage = new MemoryLayoutStorage();
  const layoutUrl = params.get("amexLayout");
  if (layoutUrl) {
    const data = await (await fetch(layoutUrl)).json();
    const now = new Date().toISOString();
    await layoutStorage.put("local", {
      id: LAYOUT_ID,
      name: "amex",
      permission: "CREATOR_WRITE",
      baseline: { data, savedAt: now },
      working: undefined,
      syncInfo: undefined,
    });
    if (!params.has("layoutId")) {
      const url = new URL(window.location.href);
      url.searchParams.set("layoutId", LAYOUT_ID);
      window.history.replaceState(undefined, "", url.href);
    }
  }
  const appConfiguration = new LocalStorageAppConfiguration({
    [S.AppSetting.LAUNCH_PREFERENCE]: S.LaunchPreferenceValue.WEB,
    [S.AppSetting.TELEMETRY_ENABLED]: false,
    [S.AppSetting.CRASH_REPORTING_ENABLED]: false,
    [S.AppSetting.UPDATES_ENABLED]: false,
    [S.AppSetting.HIDE_SIGN_IN_PROMPT]: true,
    [S.AppSetting.SHOW_OPEN_DIALOG_ON_STARTUP]: false,
  });
  await S.initI18n();
  const dataSources = [
    new S.McapLocalDataSourceFactory(),
    new S.RemoteDataSourceFactory(),
    new S.FoxgloveWebSocketDataSourceFactory(),
  ];
  const app = React.createElement(S.App, {
    deepLinks: [window.location.href],
    dataSources,
    appConfiguration,
    layoutStorage,
    extensionLoaders: [],
    enableGlobalCss: true,
  });
  ReactDOM.render(app, document.getElementById("root"));
}

main().catch((error) => {
  document.getElementById("root").textContent = `amex viewer: ${error}`;
  console.error(error);
});
