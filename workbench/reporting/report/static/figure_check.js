window.addEventListener("load", () => {
  for (const img of document.querySelectorAll("img")) {
    const loaded = img.complete && img.naturalWidth > 0;
    img.setAttribute("data-loaded", loaded ? "yes" : "no");
    if (!loaded) {
      const note = document.createElement("p");
      note.className = "missing";
      note.textContent = "Figure file not found beside this page: " + img.getAttribute("src");
      img.after(note);
    }
  }
});
