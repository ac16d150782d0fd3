// odmd-bench leaderboard site: sorting and filtering; the view lives in the URL query.
// index.html?board=BOARD&sort=KEY&order=asc|desc&calibrated=..&input=..&training=..&selection=..
(function () {
  "use strict";
  document.documentElement.classList.add("js");
  var FACETS = ["calibrated", "input", "training", "selected_on", "selection"];
  var form = document.getElementById("controls");
  var tables = Array.prototype.slice.call(document.querySelectorAll("table[data-board]"));
  document.querySelectorAll("button.copy").forEach(function (b) {
    b.hidden = false;
    b.addEventListener("click", function () {
      var text = document.getElementById(b.getAttribute("data-for")).textContent;
      if (navigator.clipboard) { navigator.clipboard.writeText(text); }
      b.textContent = "copied";
    });
  });
  if (!form) { return; }
  var sections = Array.prototype.slice.call(document.querySelectorAll("section[data-board-section]"));
  var boards = sections.map(function (s) { return s.getAttribute("data-board-section"); });
  var keys = {};
  tables.forEach(function (t) {
    t.querySelectorAll("th[data-key]").forEach(function (th) { keys[th.getAttribute("data-key")] = true; });
  });

  function choices(name) {
    var sel = form.elements[name];
    return sel ? Array.prototype.map.call(sel.options, function (o) { return o.value; }) : [];
  }

  // The view the address asks for; with report, what of it cannot be shown is said on the page
  // (a mistyped board or column would otherwise silently show another view).
  function read(report) {
    var q = new URLSearchParams(window.location.search);
    var state = { board: q.get("board") || "", sort: q.get("sort") || "", order: q.get("order") || "asc", facets: {} };
    var problems = [];
    if (boards.indexOf(state.board) < 0) {
      if (state.board) {
        problems.push("board=" + state.board + " is not a board of this site (" + boards.join(", ") +
                      "); every board is shown");
      }
      state.board = "";
    }
    if (!keys[state.sort]) {
      if (state.sort) {
        problems.push("sort=" + state.sort + " is not a column (" + Object.keys(keys).join(", ") +
                      "); the board order is shown");
      }
      state.sort = "";
    }
    if (state.order !== "desc" && state.order !== "asc") {
      problems.push("order=" + state.order + " is neither asc nor desc; ascending is shown");
    }
    if (state.order !== "desc") { state.order = "asc"; }
    FACETS.forEach(function (f) {
      var v = q.get(f) || "";
      if (v && choices(f).indexOf(v) < 0) {
        problems.push(f + "=" + v + " is not one of " + choices(f).filter(Boolean).join(", ") +
                      "; rows are not filtered on " + f);
      }
      state.facets[f] = choices(f).indexOf(v) >= 0 ? v : "";
    });
    q.forEach(function (v, k) {
      if (k !== "board" && k !== "sort" && k !== "order" && FACETS.indexOf(k) < 0) {
        problems.push(k + " is not a setting of the view (board, sort, order, " + FACETS.join(", ") + "); ignored");
      }
    });
    if (report) { say(problems); }
    return state;
  }

  function say(problems) {
    var box = document.getElementById("view-problems");
    if (!box) { return; }
    box.textContent = "";
    if (problems.length) {
      var head = document.createElement("strong");
      head.textContent = "The address asks for a view this page cannot show: ";
      box.appendChild(head);
      box.appendChild(document.createTextNode(problems.join("; ") + "."));
    }
    box.hidden = !problems.length;
  }

  function write(state) {
    var q = new URLSearchParams();
    if (state.board) { q.set("board", state.board); }
    if (state.sort) { q.set("sort", state.sort); q.set("order", state.order); }
    FACETS.forEach(function (f) { if (state.facets[f]) { q.set(f, state.facets[f]); } });
    var text = q.toString();
    window.history.replaceState(null, "", window.location.pathname + (text ? "?" + text : "") + window.location.hash);
  }

  function value(row, key, numeric) {
    var cell = row.querySelector('td[data-k="' + key + '"]');
    if (!cell) { return null; }
    var v = cell.getAttribute("data-v");
    if (v === null || v === "") { return null; }
    return numeric ? parseFloat(v) : v.toLowerCase();
  }

  function sortTable(table, key, order) {
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    var th = table.querySelector('th[data-key="' + key + '"]');
    table.querySelectorAll("th[data-key]").forEach(function (h) { h.removeAttribute("aria-sort"); });
    var sign = order === "desc" ? -1 : 1;
    var numeric = th ? th.getAttribute("data-type") === "num" : false;
    rows.sort(function (a, b) {
      var pa = +a.getAttribute("data-pos"), pb = +b.getAttribute("data-pos");
      if (!th) { return pa - pb; }
      var va = value(a, key, numeric), vb = value(b, key, numeric);
      if (va === null || vb === null) { return va === vb ? pa - pb : (va === null ? 1 : -1); }
      if (va < vb) { return -sign; }
      if (va > vb) { return sign; }
      return pa - pb;
    });
    if (th) { th.setAttribute("aria-sort", order === "desc" ? "descending" : "ascending"); }
    rows.forEach(function (r) { body.appendChild(r); });
  }

  function apply(state) {
    var shown = 0, total = 0;
    sections.forEach(function (s) {
      s.hidden = !!state.board && s.getAttribute("data-board-section") !== state.board;
    });
    tables.forEach(function (table) {
      sortTable(table, state.sort, state.order);
      Array.prototype.forEach.call(table.tBodies[0].rows, function (row) {
        var keep = FACETS.every(function (f) {
          return !state.facets[f] || row.getAttribute("data-" + f) === state.facets[f];
        });
        row.hidden = !keep;
        if (!table.closest("section").hidden) { total += 1; if (keep) { shown += 1; } }
      });
    });
    form.elements.board.value = state.board;
    form.elements.sort.value = state.sort;
    form.elements.order.value = state.order;
    FACETS.forEach(function (f) { if (form.elements[f]) { form.elements[f].value = state.facets[f]; } });
    document.getElementById("shown").textContent = shown + " of " + total + " rows shown";
  }

  function fromForm() {
    var state = { board: form.elements.board.value, sort: form.elements.sort.value,
                  order: form.elements.order.value, facets: {} };
    FACETS.forEach(function (f) { state.facets[f] = form.elements[f] ? form.elements[f].value : ""; });
    return state;
  }

  form.addEventListener("change", function () { var s = fromForm(); write(s); say([]); apply(s); });
  form.addEventListener("submit", function (e) { e.preventDefault(); });
  tables.forEach(function (table) {
    table.querySelectorAll("th[data-key] button").forEach(function (button) {
      button.addEventListener("click", function () {
        var state = read();
        var key = button.parentNode.getAttribute("data-key");
        state.order = state.sort === key && state.order === "asc" ? "desc" : "asc";
        state.sort = key;
        write(state);
        say([]);
        apply(state);
      });
    });
  });
  apply(read(true));
}());
