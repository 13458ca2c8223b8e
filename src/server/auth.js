// Read access for the pages of a server started with `--tokens`. A browser cannot add an
// Authorization header to a page it opens or to an EventSource, so the page is opened as
// `/jobs/ID#token=TOKEN` (a read token): the fragment never reaches the server or its logs. The
// token is kept in the cookie `signorini_read` (this server's pages only, SameSite=Strict), which
// the server takes for reads and never for a write; the fragment is then removed from the
// address bar. Without a token such a server refuses the page's reads, and the page says how to
// give it one.
(() => {
  const token = new URLSearchParams(location.hash.slice(1)).get("token");
  if (token) {
    const secure = location.protocol === "https:" ? "; Secure" : "";
    document.cookie = `signorini_read=${encodeURIComponent(token)}; path=/; SameSite=Strict${secure}`;
    history.replaceState(null, "", location.pathname + location.search);
  }
  fetch("/v1/capabilities", { method: "HEAD" }).then(r => {
    if (r.status !== 401 && r.status !== 403) return;
    const p = document.createElement("p");
    p.id = "auth";
    p.style.color = "#b00";
    p.textContent = r.status === 401
      ? "This server needs a read token: open this page as " + location.pathname + "#token=YOUR_TOKEN"
      : "This token may not read this server's jobs.";
    document.body.prepend(p);
  });
})();
