"""The students' self-check web server (``grader serve``): page, JSON API and live preview."""
