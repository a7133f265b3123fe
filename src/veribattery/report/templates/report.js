// The report's only script: collapsing, and showing every row of a long breakdown.
// The page reads completely without it (every section is plain HTML).
(function () {
  "use strict";
  document.documentElement.classList.add("js");

  function setAll(open) {
    document.querySelectorAll("details").forEach(function (d) { d.open = open; });
  }
  var expand = document.getElementById("expand-all");
  var collapse = document.getElementById("collapse-all");
  if (expand) expand.addEventListener("click", function () { setAll(true); });
  if (collapse) collapse.addEventListener("click", function () { setAll(false); });

  // Long breakdown tables show their first rows; a button shows the rest.
  document.querySelectorAll("table.breakdown").forEach(function (table) {
    var hidden = table.querySelectorAll("tr.more").length;
    if (!hidden) return;
    var total = table.tBodies[0].rows.length;
    var button = document.createElement("button");
    button.type = "button";
    button.className = "more-rows";
    button.setAttribute("aria-expanded", "false");
    button.textContent = "Show all " + total + " groups";
    button.addEventListener("click", function () {
      var open = table.classList.toggle("open");
      button.setAttribute("aria-expanded", open ? "true" : "false");
      button.textContent = open ? "Show the first " + (total - hidden) + " groups"
        : "Show all " + total + " groups";
    });
    table.insertAdjacentElement("afterend", button);
  });

  // Printing: the failure paths' steps belong in the document; restore afterwards.
  var opened = [];
  window.addEventListener("beforeprint", function () {
    opened = [];
    document.querySelectorAll("details.path-steps:not([open])").forEach(function (d) {
      d.open = true;
      opened.push(d);
    });
  });
  window.addEventListener("afterprint", function () {
    opened.forEach(function (d) { d.open = false; });
    opened = [];
  });
})();
