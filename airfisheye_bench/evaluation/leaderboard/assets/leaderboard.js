"use strict";
// Sortable leaderboard tables and entry detail views; no dependency, nothing fetched.

// Missing values ("" in data-value) stay last in either direction; equal keys keep their order (stable sort).
function sortRows(body, column, numeric, descending) {
  const key = (row) => {
    const cell = row.cells[column];
    return cell.dataset.value ?? cell.textContent.trim();
  };
  const rows = Array.from(body.rows);
  rows.sort((a, b) => {
    const x = key(a);
    const y = key(b);
    if (x === "" || y === "") return (x === "") - (y === "");
    const order = numeric ? Number(x) - Number(y) : x.localeCompare(y);
    return descending ? -order : order;
  });
  body.append(...rows);
}

// A button in every header cell: the first click sorts best first (data-first), the next one reverses.
for (const table of document.querySelectorAll("table.board")) {
  const headers = Array.from(table.tHead.rows[0].cells);
  headers.forEach((th, column) => {
    th.querySelector("button").addEventListener("click", () => {
      const current = th.getAttribute("aria-sort");
      const next = current ? (current === "ascending" ? "descending" : "ascending") : th.dataset.first;
      for (const other of headers) other.removeAttribute("aria-sort");
      th.setAttribute("aria-sort", next);
      sortRows(table.tBodies[0], column, th.dataset.type === "number", next === "descending");
    });
  });
}

// A link to an entry (#entry-...) opens its detail view, also when the page is opened with that address.
function openFromHash() {
  const target = location.hash ? document.getElementById(location.hash.slice(1)) : null;
  if (target instanceof HTMLDetailsElement) {
    target.open = true;
    target.scrollIntoView({ block: "start" });
  }
}
window.addEventListener("hashchange", openFromHash);
openFromHash();
