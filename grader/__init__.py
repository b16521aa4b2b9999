"""grader: answer keys, autograding, assessment reports and sim-to-real diagnosis
for the hydraulic servo positioner lab (ME422-style mechanical controls course).

Reading order: ``units`` and ``errors``; the pure core ``model`` (physics) and
``identify`` (the students' procedure); ``datasets`` (lab data format) and
``keys``; the product layers ``grading``, ``exports``, ``assess``, ``gap``,
``report``; and at the edge ``cli``.
"""

__version__ = "0.1.0"
