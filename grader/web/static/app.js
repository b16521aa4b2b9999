// The self-check page: live preview (server-side parse, KaTeX render), form -> submission document, results.
// Every server text is inserted with textContent (never as HTML).
"use strict";
(function () {
  const form = document.getElementById("form");
  const status = document.getElementById("status");
  const timers = {};

  async function postJSON(url, body) {
    const r = await fetch(url, {method: "POST", headers: {"Content-Type": "application/json"}, body: JSON.stringify(body)});
    return [r, await r.json().catch(() => ({error: "the server sent an unreadable reply"}))];
  }

  function showPreview(el, data) {
    el.textContent = "";
    el.classList.toggle("error", Boolean(data.error));
    if (data.error) { el.textContent = data.error; return; }
    if (!data.latex) return;
    const math = document.createElement("span");
    try { window.katex.render("\\displaystyle " + data.latex, math, {throwOnError: false}); }
    catch (e) { math.textContent = data.read_as; }
    const read = document.createElement("div");
    read.className = "read";
    read.textContent = "read as: " + data.read_as;
    el.append(math, read);
    fitMath(el, math);
  }

  // A wide expression on a narrow screen: shrink it to fit, down to 80 % (still legible); beyond that the box scrolls sideways
  // and the "read as" line below it wraps.
  function fitMath(box, math) {
    math.style.fontSize = "";
    const over = math.scrollWidth / Math.max(box.clientWidth, 1);
    if (over > 1) math.style.fontSize = Math.max(0.8, 1 / over).toFixed(3) + "em";
  }

  function schedulePreview(input) {
    const item = input.name, el = document.getElementById("p-" + item);
    if (!el) return;
    clearTimeout(timers[item]);
    timers[item] = setTimeout(async () => {
      const text = input.value;
      if (!text.trim()) { showPreview(el, {}); return; }
      const [r, data] = await postJSON("api/preview", {item: item, text: text});
      if (input.value === text) showPreview(el, r.ok ? data : {});
    }, 250);
  }

  // "Kp=10, Ki=20: -1+2j, -1-2j, -3" per line -> {Kp, Ki, Kd, poles}; anything else is sent as typed.
  function readPoles(text) {
    const t = text.trim();
    if (t.startsWith("[") || t.startsWith("{")) { try { return JSON.parse(t); } catch (e) { return text; } }
    const out = [];
    for (const line of t.split(/[\n;]+/).map(s => s.trim()).filter(Boolean)) {
      const m = line.match(/^([^:]+):(.+)$/);
      if (!m) return text;
      const gains = {Kp: null, Ki: 0, Kd: 0};
      for (const part of m[1].split(",").map(s => s.trim()).filter(Boolean)) {
        const g = part.match(/^(?:(Kp|Ki|Kd)\s*=\s*)?(.+)$/);
        gains[g[1] || "Kp"] = g[2].trim();
      }
      out.push({Kp: gains.Kp, Ki: gains.Ki, Kd: gains.Kd, poles: m[2].split(",").map(s => s.trim()).filter(Boolean)});
    }
    return out;
  }

  // "Kp = 46, Kd = 0.2 s, overshoot = 13.8 %" -> {Kp, Kd, overshoot}; without "=" it is sent as typed.
  function readDesign(text) {
    if (!text.includes("=")) return text;
    const out = {};
    for (const part of text.split(/[,;\n]+/).map(s => s.trim()).filter(Boolean)) {
      const m = part.match(/^([A-Za-z_]+)\s*=\s*(.*)$/);
      if (!m) return text;
      if (m[2].trim()) out[m[1]] = m[2].trim();  // "Kd =" left blank: the check says Kd is missing
    }
    return out;
  }

  function answers() {
    const out = {};
    for (const el of form.querySelectorAll("[data-kind]")) {
      const text = el.value.trim();
      if (!text) continue;
      const kind = el.dataset.kind;
      out[el.name] = kind === "poles" ? readPoles(text) : kind === "design" ? readDesign(text) : text;
    }
    return out;
  }

  // Results of the last check, or none (data = {}): each box shows its item's status and feedback, its input is marked
  // aria-invalid when unreadable, and the status line counts the statuses (the boxes themselves are not live regions).
  function showResults(data) {
    for (const el of form.querySelectorAll(".result")) { el.textContent = ""; el.className = "result"; }
    for (const el of form.querySelectorAll("[data-kind]")) el.removeAttribute("aria-invalid");
    const counts = {};
    for (const it of data.items || []) {
      counts[it.status] = (counts[it.status] || 0) + 1;
      const el = form.querySelector('[data-testid="result-' + CSS.escape(it.item) + '"]');
      if (!el) continue;
      const word = document.createElement("span");
      word.className = "status";
      word.textContent = it.status.replace(/_/g, " ");
      el.append(word, document.createTextNode(" " + it.feedback));
      el.classList.add(it.status);
      const input = document.getElementById("a-" + it.item);
      if (input && it.status === "invalid") input.setAttribute("aria-invalid", "true");
    }
    const notes = document.getElementById("notes");
    notes.textContent = "";
    for (const n of data.notes || []) { const li = document.createElement("li"); li.textContent = n; notes.append(li); }
    return Object.entries(counts).map(([k, v]) => v + " " + k.replace(/_/g, " ")).join(", ");
  }

  async function check(ev) {
    ev.preventDefault();
    const button = document.getElementById("check");
    const file = document.getElementById("upload").files[0];
    button.disabled = true;
    showResults({});  // a failed check must not leave the previous results looking current
    status.className = "";
    status.textContent = "checking…";
    try {
      let r, data;
      if (file) {
        const body = new FormData();
        body.append("file", file);
        r = await fetch("api/check-file", {method: "POST", body: body});
        data = await r.json().catch(() => ({error: "the server sent an unreadable reply"}));
      } else {
        [r, data] = await postJSON("api/check", {station: document.getElementById("station").value, answers: answers()});
      }
      if (!r.ok) { status.className = "error"; status.textContent = data.error || ("error " + r.status); return; }
      const summary = showResults(data);
      const notes = (data.notes || []).length ? "; see the notes below" : "";
      status.textContent = (file ? "checked the file " + file.name : "checked") + ": " + (summary || "no items") + notes;
    } catch (e) {
      status.className = "error";
      status.textContent = "could not reach the server";
    } finally {
      button.disabled = false;
    }
  }

  const upload = document.getElementById("upload"), fileNote = document.getElementById("file-note");
  function showFile() { fileNote.hidden = !upload.files.length; }
  upload.addEventListener("change", showFile);
  document.getElementById("clear-file").addEventListener("click", () => { upload.value = ""; showFile(); upload.focus(); });
  showFile();  // a file the browser kept across a reload
  form.addEventListener("submit", check);
  document.getElementById("check").disabled = false;  // without JavaScript the form cannot be sent (see <noscript>)
  for (const el of form.querySelectorAll('[data-kind="expression"], [data-kind="quantity"]')) {
    el.addEventListener("input", () => schedulePreview(el));
  }
})();
