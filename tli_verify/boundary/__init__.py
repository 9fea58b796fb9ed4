"""Mode boundaries learned online: cutting planes (cuts.py) and DS modulation (modulation.py).

Paper Sec. 5.2, Thm. 1 and appendix E.3.
"""
