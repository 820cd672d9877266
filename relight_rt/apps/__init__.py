"""What is built on the Relighter: a person put into a scene or a panorama, folders and Ray jobs, render passes,
the studio, the reference's checkpoints."""
