"""Deployment: the gate (``tli gate``) orchestrates the checks of every layer below it -- the
logic (specs re-check), certify (certificates re-check exactly), verify and sim (campaign
evidence, re-run on seeds it derives itself). Nothing below imports it."""
