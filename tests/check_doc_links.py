#!/usr/bin/env python3
"""Checks the documentation: every relative link and image in README.md and docs/*.md points to a
file or folder in the repository, and no tracked file mentions the team's notes outside the repository.

Usage: check_doc_links.py REPOSITORY
"""
import glob
import os
import re
import subprocess
import sys

# [text](target) and ![alt](target), target up to the first space or ')'; <img src="...">.
MARKDOWN_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HTML_SOURCE = re.compile(r"<img[^>]*\ssrc=\"([^\"]+)\"")
# The team's notes outside the repository, which users do not have; spelled in two parts so that
# this file does not mention them.
PRIVATE_NAMES = ["shared" + "/", "DESIGN" + ".md", "STYLE" + ".md"]


def strip_code(text):
    """Markdown without fenced code blocks and inline code, where links are not links."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else ".")
    failures = []
    pages = [os.path.join(root, "README.md")] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    checked = 0
    for page in pages:
        with open(page, encoding="utf-8") as file:
            text = strip_code(file.read())
        for target in MARKDOWN_LINK.findall(text) + HTML_SOURCE.findall(text):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue  # a URL or an anchor in the same page
            path = os.path.normpath(os.path.join(os.path.dirname(page), target.split("#")[0]))
            checked += 1
            if not path.startswith(root + os.sep) and path != root:
                failures.append(f"{os.path.relpath(page, root)}: '{target}' leaves the repository")
            elif not os.path.exists(path):
                failures.append(f"{os.path.relpath(page, root)}: '{target}' does not exist")
    print(f"{checked} relative links in {len(pages)} pages")

    for name in PRIVATE_NAMES:
        tracked = subprocess.run(["git", "-C", root, "grep", "-l", "-I", "-F", name],
                                 capture_output=True, text=True)
        if tracked.returncode == 128:
            print("not a git checkout: tracked files not checked")
            break
        if tracked.returncode > 1:
            failures.append(f"git grep failed: {tracked.stderr.strip()}")
        for path in tracked.stdout.split():
            failures.append(f"{path}: mentions '{name}', which users do not have")

    for failure in failures:
        print("FAIL", failure, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
