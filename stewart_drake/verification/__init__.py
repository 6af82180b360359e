"""A motion measured on a real phantom judged against the reference it was asked to follow:
``stewart-drake verify``, alone or with its surrogate on one clock, and the QA record a
physicist signs. Everything ``verify`` runs is here, and nothing that drives the robot.

- the measured files and their readers' options: :mod:`.measured_motion`, :mod:`.measured_span`
  (the span a recording covers), :mod:`.external_reference` (a surrogate's model as its
  reference);
- the clock and the frame: :mod:`.alignment`, :mod:`.registration_motion` (a registration from a
  measured motion);
- the judgement of one motion: :mod:`.verify` (its result, :class:`~.verify.Verification`),
  :mod:`.measured_verdict` (the verdict's words and a FAIL's causes), :mod:`.verdict_levels`
  (the action level), :mod:`.verdict_notes`, :mod:`.verdict_sensitivity`;
- the pair's judgement: :mod:`.pair_judgement`, :mod:`.pair_causes`, :mod:`.pair_report`;
- what is written: :mod:`.report`, the QA record (:mod:`.qa_record`, :mod:`.qa_record_figure`,
  :mod:`.qa_record_pdf`);
- the command: :mod:`.command` (``verify``'s options and its run), :mod:`.pair_command` (its
  surrogate's options and the command's registration), :mod:`.record_options`.

It sits above the features it joins (the organ-motion library and its report,
:mod:`stewart_drake.organ_motion`; the calibration's readers of a robot session,
:mod:`stewart_drake.calibration`), beside the robot live (:mod:`stewart_drake.live`), which it
never imports.
"""
