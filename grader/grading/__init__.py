"""Grading: read submissions, check every rubric item against the key, explain mistakes, score.

parse (submissions, answers, expressions) -> check (checks, structured, tf, units_diagnosis,
mistakes, ecf, designs) -> score and feedback (grade, pipeline); see docs/grading.md.
"""
