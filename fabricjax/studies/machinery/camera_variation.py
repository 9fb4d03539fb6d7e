"""What the day-shift and camera-frames pages each measure of the Minsight image, in the one
sentence both pages carry (`RECONCILE`): the two weigh its pixels differently, so they can
disagree about whether the fabric or the day moves it more. Each page follows it with its own
number (`day_shift`: the shares weighted by each dimension's variance; `camera_frames`: how few
pixels hold the fabrics' difference)."""

RECONCILE = (
    "Why day_shift.md and camera_frames.md disagree about the Minsight image: day_shift standardises each "
    "of the image's summary dimensions (a pixel's mean or SD over a sequence) and averages the shares over "
    "them, so the many pixels the contact barely reaches, where trials differ mostly by what is fixed per "
    "session (the reference's noise, the frames' noise level), weigh "
    "as much as the few pixels of the contact, whereas camera_frames measures noise-free frames against an "
    "exact reference in DN, which those few pixels dominate."
)
