"""Output writers: Canvas CSV, Gradescope results.json and autograder zip, feedback Markdown,
report JSON and the instructor's gradebook XLSX. Every file is written atomically and is
byte-identical for identical results."""
